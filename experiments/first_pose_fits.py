"""The lidar's first step: the first pose's extrapolation against the truth (issue 11).

``uv run python experiments/first_pose_fits.py W NOISE [W NOISE ...] [--epochs N]``: the
generalisation experiment's world ``W`` (odd: a lidar) at range noise NOISE (m), run once
as the experiment runs it (``planemap.reference_time: middle``, the default), its run at
the sweeps' middles kept, and brought back to the epoch times with every
``planemap.first_pose`` (:func:`planodom.odometry.planemap.midtime.first_pose`) and with
``exact``, the first pose placed by the truth relative to the first middle (the first
pose's floor: only the middles' errors remain). One line per fit: the first pose's
extrapolation bias from the TRUE middles (deg: what the fit errs with no estimation
error), the step 1 rotation error, the rotation rms per step over all steps (deg, ratio to
the oracle's) and the ATE (xy, aligned at the origin, mm). Only the first pose changes
between the lines: the later steps are the same.
"""

from __future__ import annotations

import argparse

import numpy as np

# the walks' per-step errors
from handheld_walks import _errors

import planodom.odometry.planemap.midtime as midtime
from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import declared_sweep, world_for
from planodom.geometry import invert_transform
from planodom.metrics import ate
from planodom.odometry import run_odometry
from planodom.oracle import run_oracle
from planodom.se3 import se3_log
from planodom.simulation.random_world import simulate_world, world_fields

FITS = ("quadratic_fit", "quadratic", "cubic")


def _angle_deg(T: np.ndarray) -> float:
    return float(np.degrees(np.linalg.norm(se3_log(T)[:3])))


def one(world_index: int, noise: float, epochs: int) -> None:
    world = world_for(world_index)
    full = simulate_world(world, noise, n_epochs=epochs, all_fields=True)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    orc = run_oracle(full.scans, full.times, world.trajectory, world.scene)
    orot, _ = _errors(orc.poses, gt)
    o_rms = float(np.sqrt(np.mean(orot**2)))
    captured: list = []
    original = midtime.at_epoch_times

    def capture(run, epoch_times, order, first="quadratic_fit"):  # noqa: ANN001, ANN202
        captured.append((run, epoch_times, order))
        return original(run, epoch_times, order, first)

    midtime.at_epoch_times = capture  # run_odometry imports it when it runs
    try:
        run_odometry(world_fields(world, full), declared_sweep(world, PlanodomConfig()))
    finally:
        midtime.at_epoch_times = original
    run, epoch_times, order = captured[-1]
    middles = np.asarray(run.times)
    M_true = world.trajectory.poses(middles)
    head = f"world {world_index} {world.description['family']} {noise * 1000:g} mm"
    for fit in (*FITS, "exact"):
        if fit == "exact":
            # the first pose from the first middle by the true motion between them
            D = invert_transform(M_true[0]) @ world.trajectory.pose(float(epoch_times[0]))
            T0 = run.poses[0] @ D
            bias = 0.0
        else:
            T0 = midtime.first_pose(middles, run.poses, float(epoch_times[0]), fit)
            T0_true = midtime.first_pose(middles, M_true, float(epoch_times[0]), fit)
            bias = _angle_deg(invert_transform(full.poses[0]) @ T0_true)
        # the run's poses relative to its first one, the first one replaced by T0
        T = np.array([midtime._pose_at(middles, run.poses, float(t), order, fit)
                      for t in epoch_times])  # fmt: skip
        T[0] = T0
        poses = invert_transform(T[0])[None] @ T
        rot, _ = _errors(poses, gt)
        rms = float(np.sqrt(np.mean(rot**2)))
        a = ate(poses, gt, align="origin", xy_only=True)["rmse"]
        print(f"{head} {fit:>13}: bias from true middles {bias:.5f} deg, step 1 {rot[0]:.5f}"
              f" deg, rotation {rms:.5f} ({rms / o_rms:.1f}x), ATE {1000 * a:.2f} mm",
              flush=True)  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("runs", nargs="+", help="world noise pairs")
    p.add_argument("--epochs", type=int, default=150)
    args = p.parse_args()
    pairs = list(zip(args.runs[::2], args.runs[1::2], strict=True))
    for w, n in pairs:
        one(int(w), float(n), args.epochs)


if __name__ == "__main__":
    main()
