"""A smoothed lap's NEES and ATE with ``smoothing.sandwich_plane_share: own`` against the
default, on one odometry (issue 14, NEESPLANE).

The lap and its odometry as ``nees_gauge.py`` loads them (``--cache DIR`` reuses the
odometry, which the option does not change), then the batch with loops once with the
default config and once with the option (each plane factor's noise model holding its own
share of its epoch's deskewing error, the sandwich the shared part); ``--arms`` may add
"twice" (a diagnostic, no option: the option's noise models with the default's sandwich,
which then counts each plane's own share twice, as STEPCOV's planes probe), "both" (the
default with ``smoothing.sandwich_relative_ends: both``, NEES6) and "own_both" (the option
with it: the relative-pose factors' deskewing error in the sandwich too). Printed per arm:
epochs, odometry and batch ATE xy (m, rmse against the truth from the first pose), mean
and median NEES5 of the smoothed poses (chi2(5)'s 95 % interval for a lap's mean: [0.83,
12.8]), loop factors kept, covariance model, and the arm's process time (the smoothing and
the covariances, each arm alone).

    uv run python experiments/plane_share_nees.py --world 142 --noise 0.02 --cache DIR
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import nees_gauge  # noqa: E402
from lap_nees_option import xy_rmse  # noqa: E402

import planodom.smoothing.sandwich as sandwich_module  # noqa: E402
from planodom.metrics import errors_nees, pose_errors  # noqa: E402
from planodom.smoothing.batch import smooth_batch  # noqa: E402


def _keep_own(out, _own):  # noqa: ANN001, ANN202
    """The "twice" arm's sandwich: the own blocks kept (counted again)."""
    return out


def main() -> None:
    parser = nees_gauge.lap_parser(__doc__.splitlines()[0])
    parser.add_argument("--arms", default="default,own", help="default, own, twice, both, own_both")
    parser.add_argument("--detail", action="store_true", help="per component: e^2/P, sizes")
    args = parser.parse_args()
    world, full, cfg, odo, rel, gt = nees_gauge.load_lap(args)
    own = cfg.updated({"smoothing.sandwich_plane_share": "own"})
    both = {"smoothing.sandwich_relative_ends": "both"}
    configs = {"default": cfg, "own": own, "twice": own}
    configs |= {"both": cfg.updated(both), "own_both": own.updated(both)}
    less_own = sandwich_module.less_own
    for name in args.arms.split(","):
        sandwich_module.less_own = _keep_own if name == "twice" else less_own
        start = time.process_time()
        res = smooth_batch(odo.planes, rel, configs[name])
        cpu = time.process_time() - start
        P = res.covariances
        n5 = np.array([np.nan]) if P is None else errors_nees(
            pose_errors(res.poses, gt)[1:], P[1:], range(5))  # fmt: skip
        loops = sum(not f.removed for f in getattr(res, "loop_factors", None) or [])
        if args.detail and P is not None:
            xi = pose_errors(res.poses, gt)[1:, :5]
            var = np.diagonal(P[1:], axis1=1, axis2=2)[:, :5]
            scale = np.array([1e3, 1e3, 1e3, 1e2, 1e2])  # mrad, cm
            print(f"  {name}: mean e^2/P (roll pitch yaw x y)",
                  np.round(np.mean(xi**2 / var, 0), 2), "rms error (mrad, cm)",
                  np.round(np.sqrt(np.mean(xi**2, 0)) * scale, 3), "median sigma",
                  np.round(np.sqrt(np.median(var, 0)) * scale, 3))  # fmt: skip
        print(
            f"world {args.world} {args.noise * 1000:g} mm {name}: epochs {len(gt)}, "
            f"odometry ATE {xy_rmse(odo.poses, gt):.4f}, batch ATE {xy_rmse(res.poses, gt):.4f}, "
            f"mean NEES5 {np.nanmean(n5):.2f} (median {np.nanmedian(n5):.2f}, "
            f"{res.covariance_model}), loop factors {loops}, cpu {cpu:.0f} s "
            f"(covariances {res.covariance_s:.0f} s wall)",
            flush=True,
        )


if __name__ == "__main__":
    main()
