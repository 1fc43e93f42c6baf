"""Mean NEES5 of a lap's batch with loops, ``smoothing.sandwich_loop_sources``
"independent" against "shared" (the same poses; issue 14, NEES2CM).

The lap and its odometry as ``nees_gauge.py`` (``--cache DIR`` reuses the odometry), the
batch with loops once with the default config but "independent"; its covariances then
computed again from the same graph and estimate with the option "shared". Printed per
lap: ATE (xy rmse, m), mean NEES5 both ways, the loop factors and the older epochs they
come from.

    uv run python experiments/loop_sources_nees.py --world 148 --noise 0.02 --cache DIR

``--time N``: the covariances (``batch_covariances`` on the captured graph and estimate)
computed N times each way, alternating independent / shared, process time per call.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import nees_gauge  # noqa: E402  (patches the batch to capture its graph)

from planodom.metrics import errors_nees, pose_errors  # noqa: E402
from planodom.smoothing.batch import smooth_batch  # noqa: E402
from planodom.smoothing.batch_covariances import covariance_graph  # noqa: E402
from planodom.smoothing.loop_sources import loop_source_maps  # noqa: E402


def main() -> None:
    parser = nees_gauge.lap_parser(__doc__.splitlines()[0])
    parser.add_argument("--time", type=int, default=0, help="repeats of the CPU timing")
    args = parser.parse_args()
    world, full, cfg, odo, rel, gt = nees_gauge.load_lap(args)
    cfg = cfg.updated({"smoothing.sandwich_loop_sources": "independent"})
    res = smooth_batch(odo.planes, rel, cfg)
    assert res.covariances is not None, res.covariance_note
    cap = nees_gauge.CAPTURED
    builder = cap["builder"]
    on = cfg.updated({"smoothing.sandwich_loop_sources": "shared"}).smoothing
    cov_graph = covariance_graph(
        cap["graph"], cap["gaussian"], cap["estimate"], on.covariance_inlier_quantile
    )
    maps, cols = loop_source_maps(cov_graph, len(gt), on.delta_max)
    builder.config = on
    _, P_on, note, _, model = nees_gauge.ORIGINAL(
        builder, cap["graph"], cap["gaussian"], cap["fallback"], cap["estimate"], cap["n"],
        cap["planes"], cap["rel"],
    )  # fmt: skip
    assert P_on is not None, note
    xi = pose_errors(res.poses, gt)
    ate = float(np.sqrt(np.mean(np.sum(xi[:, 3:5] ** 2, axis=1))))
    off5 = np.nanmean(errors_nees(xi[1:], res.covariances[1:], range(5)))
    on5 = np.nanmean(errors_nees(xi[1:], P_on[1:], range(5)))
    print(f"world {args.world} noise {args.noise} epochs {len(gt)} ATE(body xy) {ate:.4f} "
          f"model {model} loop factors {len(maps)} from {len(cols)} epochs "
          f"NEES5 independent {off5:.2f} shared {on5:.2f}")  # fmt: skip
    if args.time:
        _time_covariances(builder, cfg.smoothing, on, cap, args.time)


def _time_covariances(builder, off, on, cap, repeats: int) -> None:  # noqa: ANN001
    """Process time of the batch's covariances, independent and shared, alternating."""
    times: dict[str, list[float]] = {"independent": [], "shared": []}
    for _ in range(repeats):
        for name, config in (("independent", off), ("shared", on)):
            builder.config = config
            t0 = time.process_time()
            nees_gauge.ORIGINAL(
                builder, cap["graph"], cap["gaussian"], cap["fallback"], cap["estimate"],
                cap["n"], cap["planes"], cap["rel"],
            )  # fmt: skip
            times[name].append(time.process_time() - t0)
    off_t, on_t = np.median(times["independent"]), np.median(times["shared"])
    print(f"covariance CPU s (median of {repeats}) independent {off_t:.2f} shared {on_t:.2f} "
          f"ratio {on_t / off_t:.3f}; all: {times}")  # fmt: skip


if __name__ == "__main__":
    main()
