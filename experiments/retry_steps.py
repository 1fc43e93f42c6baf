"""The steps a configuration change moves on a built-in scene (issue 11, RETRY15).

``uv run python experiments/retry_steps.py [--scene random-outdoor] [--noise 0.006]
[--set KEY=VALUE ...]``: the scene as ``planodom run --scenario`` simulates it, run with
the default configuration and with the ``--set`` overrides (default: the old
``odometry.retry_accepts: degenerate``); one line per step whose status differs or whose
rotation error (deg, against the truth) moves by more than 0.05 deg, then both runs'
per-epoch rotation rms.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from builtin_scenes import config_with, simulated  # noqa: E402

from planodom.metrics import per_epoch_errors, relative_motions  # noqa: E402
from planodom.odometry import run_odometry  # noqa: E402


def rotation_errors(poses: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """(E - 1,) each step's rotation error, deg (roll, pitch, yaw combined)."""
    e = per_epoch_errors(relative_motions(poses), relative_motions(gt))
    return np.degrees(np.sqrt(e["roll"] ** 2 + e["pitch"] ** 2 + e["yaw"] ** 2))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default="random-outdoor")
    p.add_argument("--noise", default="0.006")
    p.add_argument("--set", action="append", default=None, metavar="KEY=VALUE")
    args = p.parse_args()
    sets = args.set or ["odometry.retry_accepts=degenerate"]
    sim, gt = simulated(args.scene, args.noise)
    a = run_odometry(sim, config_with([]), sim.rig)
    b = run_odometry(sim, config_with(sets), sim.rig)
    ea, eb = rotation_errors(np.asarray(a.poses), gt), rotation_errors(np.asarray(b.poses), gt)
    print("step  default  with-set | rotation error deg, default  with-set")
    for k in range(1, len(a.statuses)):
        if a.statuses[k] != b.statuses[k] or abs(ea[k - 1] - eb[k - 1]) > 0.05:
            print(f"{k:4d}  {a.statuses[k]:>10} {b.statuses[k]:>10} | "
                  f"{ea[k - 1]:8.3f} {eb[k - 1]:8.3f}")  # fmt: skip
    print(f"rotation rms deg: default {np.sqrt(np.mean(ea**2)):.4f}, "
          f"with {' '.join(sets)} {np.sqrt(np.mean(eb**2)):.4f}")  # fmt: skip


if __name__ == "__main__":
    main()
