"""A smoothed lap's NEES and ATE with the default config and with ``--set`` overrides
that change the odometry (issue 14, DESKEWCOV).

One lap of a 2D-rig world as ``nees_gauge.py`` loads it (``planodom experiment loops``'
lap, the odometry as ``planodom smooth`` runs it, the batch with loops with the default
covariances: the sandwich on these laps), run with each config in this process. Printed
per config: epochs, odometry ATE xy, batch ATE xy (m, rmse of the xy errors), mean NEES5
of the smoothed poses (chi2(5)'s 95 % interval for a lap's mean: [0.83, 12.8], as
NEES6), the odometry's unresolved epochs.

``--probe-planes`` (a probe): also the default's odometry (with the planes' Jacobians)
smoothed with its planes' covariances holding the deskewing error (``plane_deskew.
with_deskew_noise``, sized by the run-wide change of ``step_nees.run_change``) and its
steps as they are: the smoothing's share of ``plane_deskew_noise: change`` without the
odometry's estimate changing.

    uv run python experiments/lap_nees_option.py --world 150 --noise 0.02 \
        --set odometry.plane_deskew_noise=change
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
from builtin_scenes import config_with
from step_nees import run_change

from planodom.experiments.generalisation import world_for
from planodom.geometry import invert_transform
from planodom.metrics import errors_nees, pose_errors
from planodom.odometry import run_odometry
from planodom.odometry.plane_deskew import with_deskew_noise
from planodom.simulation.random_world import simulate_world, world_fields
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.run import smoothing_config, smoothing_relatives


def xy_rmse(poses: np.ndarray, gt: np.ndarray) -> float:
    """RMSE (m) of the xy position errors of ``poses`` (E, 4, 4) against ``gt``."""
    d = poses[:, :2, 3] - gt[:, :2, 3]
    return float(np.sqrt(np.mean(np.sum(d**2, axis=1))))


def inflated_planes(odo, run) -> list:  # noqa: ANN001
    """The run's planes with the deskewing error of the run-wide change (module docstring)."""
    cov = run_change(odo)
    sigma = (float(np.sqrt(np.trace(cov[:3, :3]))), float(np.sqrt(np.trace(cov[3:, 3:]))))
    out = []
    for k, planes in enumerate(odo.planes):
        r = odo.results[k]
        twist = None if r is None else r.deskew_twist
        out.append(with_deskew_noise(planes, run[k], twist, sigma))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", type=int, required=True)
    parser.add_argument("--noise", type=float, required=True)
    parser.add_argument(
        "--set", nargs="*", action="extend", default=[], help="the option's overrides key=value"
    )
    parser.add_argument("--probe-planes", action="store_true", help="the planes-only probe")
    args = parser.parse_args()
    world = world_for(args.world)
    full = simulate_world(world, args.noise, all_fields=True)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    run = world_fields(world, full)
    configs = [("default", []), ("option", args.set)]
    if args.probe_planes:
        configs.append(("planes probe", []))
    for name, sets in configs:
        cfg = config_with(sets).updated({"smoothing.loop_closure": True})
        odo = run_odometry(run, smoothing_config(cfg))
        if name == "planes probe":
            odo = dataclasses.replace(odo, planes=inflated_planes(odo, run))
        res = smooth_batch(odo.planes, smoothing_relatives(odo, cfg), cfg)
        P = res.covariances
        nees = np.nan if P is None else float(np.nanmean(errors_nees(
            pose_errors(res.poses, gt)[1:], P[1:], range(5))))  # fmt: skip
        print(
            f"world {args.world} {args.noise * 1000:g} mm {name}: epochs {len(gt)}, "
            f"odometry ATE {xy_rmse(odo.poses, gt):.4f}, batch ATE {xy_rmse(res.poses, gt):.4f}, "
            f"mean NEES5 {nees:.2f} ({res.covariance_model}), unresolved {odo.n_unresolved}",
            flush=True,
        )


if __name__ == "__main__":
    main()
