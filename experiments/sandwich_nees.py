"""Fitted against sandwich covariances of the batch with loops on the 2D-rig closed laps.

For each world and range noise, one lap is simulated (as ``planodom experiment loops``),
the odometry run twice (``smoothing.covariance_model: fitted`` without the planes'
deskewing Jacobians; ``sandwich``, whose extraction computes ``Plane.deskew_jacobian``;
once with ``--single-odometry``), and the batch with loop closure run on each. Per run:
whether the odometry's and the smoothed poses are bit-identical, ATE (xy, origin-aligned)
of both, mean NEES of the 5 observed DoF (chi2(5), 95 % per run [0.83, 12.8]) of both,
and the covariances' wall time of both (the two batch runs alternate their order from one
run to the next). ``--motion-scale``: the sandwich's ``smoothing.sandwich_motion_scale``
(default "run").

    uv run python experiments/sandwich_nees.py --worlds 0,2,4 --levels 0.006 -o OUT.csv
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import world_for
from planodom.geometry import invert_transform
from planodom.metrics import ate, pose_nees
from planodom.odometry import run_odometry
from planodom.results import write_rows
from planodom.simulation.random_world import simulate_world, world_fields
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.run import smoothing_config, smoothing_relatives


def _nees(res, gt: np.ndarray) -> float:  # noqa: ANN001
    if res.covariances is None:
        return float("nan")
    return float(np.nanmean(pose_nees(res.poses[1:], res.covariances[1:], gt[1:], range(5))))


def run(
    world_index: int, noise: float, n_epochs: int | None, order: int, single_odometry: bool,
    motion_scale: str = "run",
) -> dict:  # fmt: skip
    """One lap: both odometries (or the sandwich's for both) and both batch runs."""
    world = world_for(world_index)
    full = simulate_world(world, noise, n_epochs=n_epochs, all_fields=True)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    configs = {
        "fitted": PlanodomConfig().updated(
            {
                "smoothing.loop_closure": True,
                "smoothing.covariance_model": "fitted",
                "extraction.deskew_jacobian": False,
            }
        ),
        "sandwich": PlanodomConfig().updated(
            {
                "smoothing.loop_closure": True,
                "smoothing.covariance_model": "sandwich",
                "smoothing.sandwich_motion_scale": motion_scale,
            }
        ),
    }
    inputs: dict[str, tuple] = {}
    for name, cfg in reversed(configs.items()):
        if name == "fitted" and single_odometry:  # the sandwich's (its planes' Jacobians)
            inputs[name] = inputs["sandwich"]
            continue
        start = time.perf_counter()
        odo = run_odometry(world_fields(world, full), smoothing_config(cfg))
        inputs[name] = (odo, smoothing_relatives(odo, cfg), time.perf_counter() - start)
    results = {}
    for name in ("fitted", "sandwich")[:: 1 if order % 2 == 0 else -1]:
        odo, rel, _ = inputs[name]
        results[name] = smooth_batch(odo.planes, rel, configs[name])
    f, s = results["fitted"], results["sandwich"]
    row = {
        "world": world_index,
        "noise_mm": noise * 1e3,
        "epochs": len(gt),
        "odometry_identical": bool(
            np.array_equal(inputs["fitted"][0].poses, inputs["sandwich"][0].poses)
        ),
        "poses_identical": bool(np.array_equal(f.poses, s.poses)),
        "ate_fitted_m": _ate(f.poses, gt),
        "ate_sandwich_m": _ate(s.poses, gt),
        "nees5_fitted": _nees(f, gt),
        "nees5_sandwich": _nees(s, gt),
        "motion_scale": configs["sandwich"].smoothing.sandwich_motion_scale,
        "cov_s_fitted": f.covariance_s,
        "cov_s_sandwich": s.covariance_s,
        "batch_s_fitted": f.runtime_s,
        "batch_s_sandwich": s.runtime_s,
        "odometry_s_fitted": inputs["fitted"][2],
        "odometry_s_sandwich": inputs["sandwich"][2],
        "note_fitted": f.covariance_note or "",
        "note_sandwich": s.covariance_note or "",
    }
    return row


def _ate(poses: np.ndarray, gt: np.ndarray) -> float:
    """xy ATE (rmse), m, as ``planodom experiment loops``."""
    return float(ate(poses, gt, xy_only=True)["rmse"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", default="0,2,4,6,8,10,12,14,16,18")
    parser.add_argument("--levels", default="0.006,0.02")
    parser.add_argument("--epochs", type=int, default=None)
    parser.add_argument(
        "--single-odometry",
        action="store_true",
        help="run the odometry once (with the planes' deskewing Jacobians)",
    )
    parser.add_argument(
        "--motion-scale",
        default="run",
        choices=["none", "run"],
        help="smoothing.sandwich_motion_scale of the sandwich run (none: the changes of motion)",
    )
    parser.add_argument("-o", "--out", required=True)
    args = parser.parse_args()
    rows = []
    order = 0
    for w in [int(x) for x in args.worlds.split(",")]:
        for noise in [float(x) for x in args.levels.split(",")]:
            row = run(w, noise, args.epochs, order, args.single_odometry, args.motion_scale)
            order += 1
            rows.append(row)
            print({k: (round(v, 5) if isinstance(v, float) else v) for k, v in row.items()},
                  flush=True)  # fmt: skip
            write_rows(args.out, rows)


if __name__ == "__main__":
    main()
