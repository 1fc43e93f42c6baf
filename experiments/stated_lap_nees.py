"""A smoothed lap's NEES and ATE with ``odometry.stated_deskew_noise: shared`` against the
default, on one odometry (issue 14, STEPCOV).

The lap and its odometry as ``nees_gauge.py`` loads them (``--cache DIR`` reuses the
odometry: the option does not change it, only the steps' stated covariances), then the
batch with loops (default covariances: the sandwich) once with the default's relative
poses and once with the option's (:func:`planodom.smoothing.run.stated_steps`: every
relative pose delta 1..D states both its epochs' deskewing errors). ``--probe-planes``
(a probe, no option): also the option with the smoothing's planes' covariances holding
each plane's deskewing error of the run-wide change (DESKEWCOV's planes probe), which
the sandwich's ``Q_k`` counts again. Printed per arm: epochs, batch ATE xy (m, rmse
against the truth from the first pose), mean NEES5 of the smoothed poses (chi2(5)'s 95 %
interval for a lap's mean: [0.83, 12.8]), loop factors kept, covariance model, and the
arm's process time.

    uv run python experiments/stated_lap_nees.py --world 154 --noise 0.006 --cache DIR
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import nees_gauge  # noqa: E402
from lap_nees_option import xy_rmse  # noqa: E402

from planodom.metrics import errors_nees, pose_errors  # noqa: E402
from planodom.odometry.plane_deskew import with_deskew_noise  # noqa: E402
from planodom.smoothing.batch import smooth_batch  # noqa: E402
from planodom.smoothing.run import stated_steps  # noqa: E402


def probe_planes(odo) -> list:  # noqa: ANN001
    """The run's planes with each plane's deskewing error of the run-wide change."""
    from planodom.odometry.stated_deskew import run_twist_change

    cov = run_twist_change(odo.results, np.asarray(odo.times, dtype=float))
    sigma = (float(np.sqrt(3 * cov[0, 0])), float(np.sqrt(3 * cov[3, 3])))
    out = []
    for k, planes in enumerate(odo.planes):
        r = odo.results[k]
        if r is None or r.deskew_twist is None or r.deskew_times is None:
            out.append(list(planes))
            continue
        scan = _Span(r.deskew_times)
        out.append(with_deskew_noise(planes, scan, r.deskew_twist, sigma))  # type: ignore[arg-type]
    return out


class _Span:
    """A stand-in scan whose times span ``deskew_times`` (what ``epoch_span`` reads)."""

    def __init__(self, times: tuple[float, float]) -> None:
        self.t = np.asarray(times, dtype=float)


def main() -> None:
    parser = nees_gauge.lap_parser(__doc__.splitlines()[0])
    parser.add_argument("--probe-planes", action="store_true", help="the planes probe arm")
    args = parser.parse_args()
    world, full, cfg, odo, rel, gt = nees_gauge.load_lap(args)
    n_reused = sum(r is not None and r.curr not in odo.superseded for r in odo.results)
    option = cfg.updated({"odometry.stated_deskew_noise": "shared"})
    stated = stated_steps(odo, rel[:n_reused], rel[n_reused:])
    arms = [("default", odo.planes, rel, cfg), ("shared", odo.planes, stated, option)]
    if args.probe_planes:
        arms.append(("shared+planes probe", probe_planes(odo), stated, option))
    for name, planes, relatives, config in arms:
        start = time.process_time()
        res = smooth_batch(planes, relatives, config)
        P = res.covariances
        nees = np.nan if P is None else float(np.nanmean(errors_nees(
            pose_errors(res.poses, gt)[1:], P[1:], range(5))))  # fmt: skip
        loops = sum(not f.removed for f in getattr(res, "loop_factors", None) or [])
        print(
            f"world {args.world} {args.noise * 1000:g} mm {name}: epochs {len(gt)}, "
            f"odometry ATE {xy_rmse(odo.poses, gt):.4f}, batch ATE {xy_rmse(res.poses, gt):.4f}, "
            f"mean NEES5 {nees:.2f} ({res.covariance_model}), loop factors {loops}, "
            f"cpu {time.process_time() - start:.0f} s",
            flush=True,
        )


if __name__ == "__main__":
    main()
