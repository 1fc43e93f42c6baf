"""How much a step's yaw moves with each epoch's deskewing yaw-rate error (issue 11, SIGMA0B).

Per epoch ``k`` of ``--epochs-at`` of a built-in scene, epochs ``k - 1`` (the reference)
and ``k`` are extracted with their true constant twist (:func:`builtin_scenes.true_twist`)
and with ``--delta`` deg/s added to the yaw rate of one, the other, or both, and their
step solved (no prior); prints the step's yaw error (mdeg) for each, and its derivative
(seconds: degrees of step yaw per deg/s of rate error) against the reference's and the
epoch's error. :func:`planodom.odometry.deskew.twist_offset` takes them to be ``+tm`` and
``-tm`` (the mean point time), printed beside them.

    uv run python experiments/deskew_sensitivity.py --scene random-outdoor --noise 0 \\
        --epochs-at 240 515 516 584
"""

from __future__ import annotations

import argparse

import numpy as np
from builtin_scenes import config_with, simulated, true_twist

from planodom.extraction.pipeline import extract_planes
from planodom.metrics import relative_motions
from planodom.odometry.run import with_motion_bounds
from planodom.odometry.solver import estimate_relative_pose
from planodom.planes import PlaneSet


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="random-outdoor")
    ap.add_argument("--noise", default="0")
    ap.add_argument("--epochs-at", type=int, nargs="+", required=True)
    ap.add_argument("--delta", type=float, default=0.3, help="deg/s added to a yaw rate")
    ap.add_argument(
        "--set", nargs="*", action="extend", default=[], help="config overrides key=value"
    )
    args = ap.parse_args()
    sim, gt = simulated(args.scene, args.noise)
    cfg = with_motion_bounds(config_with(args.set), sim.rig.motion_bounds)
    true_steps, d = relative_motions(gt), np.radians(args.delta)
    origins = getattr(sim.rig, "sensor_origins", None)
    yaw = lambda T: float(np.degrees(np.arctan2(T[1, 0], T[0, 0])))  # noqa: E731
    for k in args.epochs_at:
        out = {}
        for er, ec in ((0.0, 0.0), (d, 0.0), (0.0, d), (d, d)):
            planes = []
            for j, e in ((k - 1, er), (k, ec)):
                twist = true_twist(sim, j)
                twist[2] += e
                planes.append(extract_planes(sim.scans[j], cfg.extraction, twist, origins))
            ref, cur = (PlaneSet.from_planes(p) for p in planes)
            r = estimate_relative_pose(ref, cur, cfg, None, 1.0, step=True)
            out[er, ec] = (yaw(r.T_prev_curr) - yaw(true_steps[k - 1])) * 1e3
            print(f"{k:4d} reference {np.degrees(er):+.2f} epoch {np.degrees(ec):+.2f} deg/s off: "
                  f"{r.status.name:10s} planes {len(planes[0])}/{len(planes[1])} step yaw "
                  f"{out[er, ec]:+8.2f} mdeg")  # fmt: skip
        tm = float(np.mean(sim.scans[k].t))
        ref, own = ((out[x] - out[0.0, 0.0]) / 1e3 / args.delta for x in ((d, 0.0), (0.0, d)))
        print(f"{k:4d} d(step yaw)/d(rate error): reference {ref:+.4f} s, epoch {own:+.4f} "
              f"s; twist_offset's model {tm:+.4f} / {-tm:+.4f} s")  # fmt: skip


if __name__ == "__main__":
    main()
