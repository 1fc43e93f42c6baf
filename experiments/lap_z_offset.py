"""The smoothing's odometry with and without ``odometry.z_offset_measured_only`` on laps
(issue 14, LAPZ).

Per world and range noise: one lap (``simulate_world(..., n_epochs=None)``, as
:func:`planodom.experiments.loops.run_loop_world` simulates it), the batch smoothing's
odometry (``smoothing_config``) with the option off and on. Where the two odometries
differ (poses or planes), the ``batch+loops`` row of :func:`compare_methods` is computed
for each (the same smoother, config and metrics; the other methods are skipped to save
CPU); identical odometry gives identical smoothing. One JSON line per world, noise and
setting: odometry ATE xy (m), loop end xy / height (m), steps that measured z, and for
``batch+loops`` ATE, loop end, mean NEES5, ties kept and wrong, CPU seconds.

    uv run python experiments/lap_z_offset.py --worlds 20 140 --noise 0.006 0.02 -o OUT.jsonl
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import world_for
from planodom.experiments.loops import coplanar
from planodom.geometry import invert_transform
from planodom.metrics import ate, pose_nees
from planodom.odometry import run_odometry
from planodom.simulation.random_world import simulate_world, world_fields
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.loop_records import loop_factor_counts, reidentification_counts
from planodom.smoothing.run import smoothing_config, smoothing_relatives

KEY = "odometry.z_offset_measured_only"


def errors(poses: np.ndarray, gt: np.ndarray) -> dict[str, float]:
    """As ``loops._errors``: ATE xy (origin-aligned rmse), loop end xy and height (m)."""
    end = float(np.linalg.norm(poses[-1][:2, 3] - gt[-1][:2, 3]))
    end_z = float(abs(poses[-1][2, 3] - gt[-1][2, 3]))
    return {"ate_m": ate(poses, gt, xy_only=True)["rmse"], "end_m": end, "end_z_m": end_z}


def same_odometry(a, b) -> bool:  # noqa: ANN001
    """Whether two odometry runs have the same poses and planes (bit for bit)."""
    if not np.array_equal(np.asarray(a.poses), np.asarray(b.poses)):
        return False
    if len(a.planes) != len(b.planes):
        return False
    for pa, pb in zip(a.planes, b.planes, strict=True):
        if len(pa) != len(pb):
            return False
        for x, y in zip(pa, pb, strict=True):
            if not (np.array_equal(x.normal, y.normal) and x.offset == y.offset):
                return False
    return True


def batch_loops(odo, gt: np.ndarray, config: PlanodomConfig, same) -> dict:  # noqa: ANN001
    """The ``batch+loops`` row of ``compare_methods`` on one odometry run."""
    t0 = time.process_time()
    relatives = smoothing_relatives(odo, config)
    res = smooth_batch(odo.planes, relatives, config.updated({"smoothing.loop_closure": True}))
    row = {f"bl_{k}": v for k, v in errors(res.poses, gt).items()}
    row |= reidentification_counts(res.reidentifications, same)
    row |= loop_factor_counts(res.loop_factors, gt)
    if res.covariances is not None:
        nees = pose_nees(res.poses[1:], res.covariances[1:], gt[1:], range(5))
        row["nees5"] = float(np.nanmean(nees))
    row["bl_cpu_s"] = time.process_time() - t0
    return row


def run(world_index: int, noise: float, out) -> None:  # noqa: ANN001
    """Both settings on one lap; the rows written to ``out``."""
    world = world_for(world_index)
    full = simulate_world(world, noise, n_epochs=None, all_fields=True)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    same = coplanar(world.scene)
    base = PlanodomConfig()
    runs = {}
    for on in (False, True):
        cfg = base.updated({KEY: on})
        t0 = time.process_time()
        odo = run_odometry(world_fields(world, full), smoothing_config(cfg))
        z_obs = sum(bool(r is not None and r.z_observed) for r in odo.results)
        row = {"world": world_index, "noise_mm": noise * 1e3, "on": on, "epochs": len(gt)}
        row |= {f"odo_{k}": v for k, v in errors(np.asarray(odo.poses), gt).items()}
        row |= {"z_observed": z_obs, "odo_cpu_s": time.process_time() - t0}
        runs[on] = (odo, cfg, row)
    changed = not same_odometry(runs[False][0], runs[True][0])
    for on in (False, True):
        odo, cfg, row = runs[on]
        row["changed"] = changed
        if changed:
            row |= batch_loops(odo, gt, cfg, same)
        out.write(json.dumps(row) + "\n")
        out.flush()
        print(json.dumps(row), file=sys.stderr)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", type=int, nargs="+", required=True)
    parser.add_argument("--noise", type=float, nargs="+", default=[0.006, 0.02])
    parser.add_argument("-o", "--out", required=True, help="JSON lines, appended")
    args = parser.parse_args()
    with open(args.out, "a") as out:
        for w in args.worlds:
            for noise in args.noise:
                run(w, noise, out)


if __name__ == "__main__":
    main()
