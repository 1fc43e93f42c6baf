"""Where the smoothed poses' NEES excess sits on the 2D-rig closed laps (a diagnostic).

For each world and range noise, one lap is simulated (as ``planodom experiment loops``;
``--motion snapshot``: every scan taken at one instant, no deskewing error), the odometry
run once with the planes' deskewing Jacobians, and the batch with loop closure run with
the fitted and the sandwich covariances (the same poses). Per run and covariance model:

- mean NEES5 (chi2(5), 95 % per run [0.83, 12.8]) over the epochs whose delta = 1 odometry
  step was "ok", and over those bridged by constant velocity ("degenerate": rotation
  only, "unresolved": nothing measured), with their counts;
- mean NEES of the rotation (roll, pitch, yaw; chi2(3)) and of the horizontal position
  (body x, y; chi2(2)) alone;
- ``tilt``: the mean over the lap of the poses' rotation errors in the world frame
  (mrad; one rotation between the first pose, the gauge, and the rest), its value at
  epoch 1, and the rms about the mean;
- ``ate_m``: xy ATE (rmse, origin-aligned, as ``planodom experiment loops``);
- the NEES5 once that one rotation is taken out of every pose (rotation error and the
  position error it causes about the first pose; a diagnostic, not an estimator), and
  once the mean horizontal position error in the world frame (``shift_cm``) is taken out
  too (``nees5_unshifted``: what one rigid offset of the whole lap against its first pose
  leaves).

    uv run python experiments/nees_split.py --worlds 18,0,16 --levels 0.006,0.02 -o OUT.csv
"""

from __future__ import annotations

import argparse

import numpy as np

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import world_for
from planodom.geometry import invert_transform
from planodom.metrics import ate, errors_nees, pose_errors
from planodom.odometry import run_odometry
from planodom.results import write_rows
from planodom.simulation.random_world import simulate_world, world_fields
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.run import run_smoothing, smoothing_config, smoothing_relatives


def without_rotation(poses: np.ndarray, errors: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """(E, 6) ``errors`` less those one world-frame rotation ``theta`` (3,) about the first
    pose (the world origin) causes: ``R_k^T theta`` in rotation, ``R_k^T (theta x p_k)``
    in position (first order)."""
    out = errors.copy()
    for k, T in enumerate(poses):
        R, p = T[:3, :3], T[:3, 3]
        out[k, :3] -= R.T @ theta
        out[k, 3:] -= R.T @ np.cross(theta, p)
    return out


def split(poses: np.ndarray, cov: np.ndarray | None, gt: np.ndarray, status: list[str]) -> dict:
    """The figures of one covariance model's run (epoch 0, the gauge, left out)."""
    if cov is None:
        return {}
    xi = pose_errors(poses, gt)[1:]
    P, st = cov[1:], np.array(status[1:])
    n5 = errors_nees(xi, P, range(5))
    world_rot = np.einsum("kij,kj->ki", poses[1:, :3, :3], xi[:, :3])
    theta = world_rot.mean(axis=0)
    row: dict[str, float | int | str] = {"nees5": float(np.nanmean(n5))}
    for name in ("ok", "degenerate", "unresolved"):
        mask = st == name
        row[f"n_{name}"] = int(mask.sum())
        row[f"nees5_{name}"] = float(np.nanmean(n5[mask])) if mask.any() else np.nan
    row["nees_rot3"] = float(np.nanmean(errors_nees(xi, P, range(3))))
    row["nees_xy2"] = float(np.nanmean(errors_nees(xi, P, (3, 4))))
    row["tilt_mrad"] = " ".join(f"{v:.2f}" for v in theta * 1e3)
    row["tilt_epoch1_mrad"] = " ".join(f"{v:.2f}" for v in world_rot[0] * 1e3)
    row["tilt_rms_about_mrad"] = " ".join(f"{v:.2f}" for v in world_rot.std(axis=0) * 1e3)
    fixed = without_rotation(poses[1:], xi, theta)
    row["nees5_untilted"] = float(np.nanmean(errors_nees(fixed, P, range(5))))
    row["nees_rot3_untilted"] = float(np.nanmean(errors_nees(fixed, P, range(3))))
    world_pos = np.einsum("kij,kj->ki", poses[1:, :3, :3], fixed[:, 3:])
    shift = np.append(world_pos[:, :2].mean(axis=0), 0.0)
    fixed[:, 3:] -= np.einsum("kji,j->ki", poses[1:, :3, :3], shift)
    row["shift_cm"] = " ".join(f"{v:.1f}" for v in shift[:2] * 1e2)
    row["nees5_unshifted"] = float(np.nanmean(errors_nees(fixed, P, range(5))))
    return row


def run(world_index: int, noise: float, motion: str, refresh: int = 0) -> list[dict]:
    """One lap: the odometry once, the batch with loops with both covariance models
    (``refresh``: ``smoothing.first_epoch_refresh``, through :func:`run_smoothing`)."""
    world = world_for(world_index)
    full = simulate_world(world, noise, all_fields=True, motion=motion)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    configs = {
        model: PlanodomConfig().updated(
            {
                "smoothing.loop_closure": True,
                "smoothing.covariance_model": model,
                "smoothing.first_epoch_refresh": refresh,
            }
        )
        for model in ("fitted", "sandwich")
    }
    source = world_fields(world, full)
    odo = run_odometry(source, smoothing_config(configs["sandwich"]))
    rel = smoothing_relatives(odo, configs["sandwich"])
    status = ["none"] + [("none" if r is None else str(r.status)) for r in odo.results[1:]]
    rows = []
    for model, cfg in configs.items():
        if refresh:
            res = run_smoothing(source, cfg, odometry=odo).result
        else:
            res = smooth_batch(odo.planes, rel, cfg)
        row = {
            "world": world_index,
            "noise_mm": noise * 1e3,
            "motion": motion,
            "first_epoch_refresh": refresh,
            "model": model,
            "ate_m": float(ate(res.poses, gt, xy_only=True)["rmse"]),
        }
        rows.append(row | split(res.poses, res.covariances, gt, status))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worlds", default="18,0,16")
    parser.add_argument("--levels", default="0.006,0.02")
    parser.add_argument("--motion", default="continuous", choices=["continuous", "snapshot"])
    parser.add_argument(
        "--first-epoch-refresh",
        type=int,
        default=0,
        help="smoothing.first_epoch_refresh of both batch runs (0: off, the default)",
    )
    parser.add_argument("-o", "--out", required=True)
    args = parser.parse_args()
    rows: list[dict] = []
    for w in [int(x) for x in args.worlds.split(",")]:
        for noise in [float(x) for x in args.levels.split(",")]:
            for row in run(w, noise, args.motion, args.first_epoch_refresh):
                rows.append(row)
                print({k: (round(v, 2) if isinstance(v, float) else v) for k, v in row.items()},
                      flush=True)  # fmt: skip
            write_rows(args.out, rows)


if __name__ == "__main__":
    main()
