"""A lap's mean NEES5 of the batch with loops with ``smoothing.sandwich_unmeasured``
"change" (the default) and "motion", the same poses (issue 14, NEESLAP).

The lap and its odometry as ``nees_gauge.py`` loads them (``planodom experiment loops``'
lap, the odometry as ``planodom smooth`` runs it; ``--cache DIR`` reuses it), the batch
with loops once with the default config, its covariances then computed again from the
same graph and estimate with "motion" (the option changes only the sandwich's ``Q``, so
the poses, ATE and loop factors are the default's); ``--arms`` may add "both"
(``smoothing.sandwich_relative_ends: both``, NEES6) and "both_motion" (the two together),
which change only the covariances too. Printed (and with ``--csv`` appended
as one row): epochs, the epochs the option gives a term (no measured step into them),
ATE xy (m, rmse against the truth from the first pose, as ``planodom experiment
loops``), loop factors kept, mean NEES5 each way (chi2(5)'s 95 % interval for a lap's
mean: [0.83, 12.8]) and the covariances' process time each way.

    uv run python experiments/unmeasured_nees.py --world 292 --noise 0.006 --cache DIR
"""

from __future__ import annotations

import csv
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import nees_gauge  # noqa: E402  (patches the batch to capture its graph)

from planodom.metrics import errors_nees, pose_errors  # noqa: E402
from planodom.smoothing.batch import smooth_batch  # noqa: E402
from planodom.smoothing.unmeasured import unmeasured_errors  # noqa: E402

BOTH = {"smoothing.sandwich_relative_ends": "both"}
ARMS = {
    "change": {"smoothing.sandwich_unmeasured": "change"},
    "motion": {"smoothing.sandwich_unmeasured": "motion"},
    "both": BOTH,  # NEES6's option: the relative-pose factors' ends' deskewing errors
    "both_motion": {"smoothing.sandwich_unmeasured": "motion"} | BOTH,
}


def main() -> None:
    parser = nees_gauge.lap_parser(__doc__.splitlines()[0])
    parser.add_argument("--csv", type=Path, default=None, help="append the row here")
    parser.add_argument("--arms", default="change,motion", help=", ".join(ARMS))
    args = parser.parse_args()
    world, full, cfg, odo, rel, gt = nees_gauge.load_lap(args)
    res = smooth_batch(odo.planes, rel, cfg)
    assert res.covariances is not None, res.covariance_note
    cap = nees_gauge.CAPTURED
    builder = cap["builder"]
    xi = pose_errors(res.poses, gt)
    ate = float(np.sqrt(np.mean(np.sum((res.poses[:, :2, 3] - gt[:, :2, 3]) ** 2, axis=1))))
    row: dict[str, object] = {"world": args.world, "noise_m": args.noise, "epochs": len(gt)}
    d = unmeasured_errors(cap["rel"], len(gt))
    row["epochs_with_term"] = int(np.all(np.isfinite(d), axis=1).sum())
    row["ate_m"] = ate
    row["loop_factors"] = sum(not f.removed for f in getattr(res, "loop_factors", None) or [])
    for value in args.arms.split(","):
        builder.config = cfg.updated(ARMS[value]).smoothing
        t0 = time.process_time()
        _, P, note, _, model = nees_gauge.ORIGINAL(
            builder, cap["graph"], cap["gaussian"], cap["fallback"], cap["estimate"],
            cap["n"], cap["planes"], cap["rel"],
        )  # fmt: skip
        row[f"cpu_{value}_s"] = time.process_time() - t0
        assert P is not None, note
        row[f"nees5_{value}"] = float(np.nanmean(errors_nees(xi[1:], P[1:], range(5))))
        row["model"] = model
    print(" ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in row.items()))
    if args.csv is not None:
        new = not args.csv.exists()
        with args.csv.open("a", newline="") as f:
            out = csv.DictWriter(f, fieldnames=list(row))
            if new:
                out.writeheader()
            out.writerow(row)


if __name__ == "__main__":
    main()
