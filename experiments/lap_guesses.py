"""A lap's two initial guesses of the batch against the truth (a diagnostic, issue 14, LAP362).

For one lap (``nees_gauge.load``'s cached odometry): the fixed-lag smoother's poses (the
batch's default initial guess and the loop closure's predictions) and the chained odometry
(``batch_initial: odometry``), every ``--every`` epochs their horizontal error against the
truth and the odometry's status; then the check of ``batch_initial: checked`` (the worst
squared Mahalanobis distance of the windowed guess's motion from the chained one's under
the run's drift, its span) and, over that span, each guess's relative-motion error against
the truth (which of the two is off).

    uv run python experiments/lap_guesses.py --world 362 --noise 0.006 --cache DIR
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import nees_gauge  # noqa: E402

from planodom.geometry import invert_transform, pose5_from_transform  # noqa: E402
from planodom.metrics import ate  # noqa: E402
from planodom.smoothing.batch import first_measured_step  # noqa: E402
from planodom.smoothing.initial_check import _Chain, checked_guess  # noqa: E402
from planodom.smoothing.windowed import smooth_windowed  # noqa: E402


def main() -> None:
    parser = nees_gauge.lap_parser(__doc__.splitlines()[0])
    parser.add_argument("--every", type=int, default=10)
    args = parser.parse_args()
    _, full, cfg, odo, rel = nees_gauge.load(args.world, args.noise, args.cache)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    first = cfg.updated({"smoothing.compute_covariances": False})
    windowed = smooth_windowed(odo.planes, rel, first).poses
    chain = _Chain(cfg.smoothing)
    chain.first_step = first_measured_step(rel)
    chained = chain.chain(rel, len(gt))
    for name, poses in (("odometry", odo.poses), ("chained", chained), ("windowed", windowed)):
        print(f"{name} ATE {ate(poses, gt, xy_only=True)['rmse']:.3f} m")
    for k in range(0, len(gt), args.every):
        err = [np.linalg.norm(p[k][:2, 3] - gt[k][:2, 3]) for p in (chained, windowed)]
        print(f"{k:5d} {odo.statuses[k]:11s} planes {len(odo.planes[k])} "
              f"chained {err[0]:6.2f} m windowed {err[1]:6.2f} m")  # fmt: skip
    replaced, worst, (a, b) = checked_guess(windowed, rel, cfg, first_measured_step(rel))
    print(f"check: worst chi2 {worst:.1f} over {a}-{b}, chained start: {replaced is not None}")
    truth = invert_transform(gt[a]) @ gt[b]
    for name, poses in (("chained", chained), ("windowed", windowed)):
        e = pose5_from_transform(invert_transform(truth) @ invert_transform(poses[a]) @ poses[b])
        print(f"{name} over {a}-{b}: yaw {np.degrees(e[2]):+.2f} deg, xy {e[3]:+.2f} {e[4]:+.2f} m")


if __name__ == "__main__":
    main()
