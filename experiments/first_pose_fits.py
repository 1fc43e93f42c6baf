"""The lidar's first step: the first pose's extrapolation against the truth (issue 11).

``uv run python experiments/first_pose_fits.py W NOISE [W NOISE ...] [--epochs N]
[--save DIR] [--no-oracle]``: the generalisation experiment's world ``W`` (odd: a lidar)
at range noise NOISE (m), run once as the experiment runs it (``planemap.reference_time:
middle``, the default), its run at the sweeps' middles kept (``DIR/W_NOISE.npz``), and
brought back to the epoch times with every first-pose extrapolation in :data:`FITS` and
with ``exact``, the first pose placed by the truth relative to the first middle (the
first pose's floor: only the middles' errors remain). ``--load FILE.npz ...`` evaluates
saved runs again without running them. One line per fit: the extrapolation's bias from
the TRUE middles (deg: what the fit errs with no estimation error), the step 1 rotation
error, the rotation rms per step over all steps (deg; ratio to the oracle's) and the ATE
(xy, aligned at the origin, mm). Only the first pose changes between the lines: the later
steps are the same.

``planemap.first_pose``'s choices are ``quadratic_fit`` (the least-squares quadratic over
the first five middles, the default), ``quadratic`` (through three), ``cubic`` (through
four); the others here are candidates: ``geodesic`` (through two), ``cubic_fitN`` /
``quadratic_fitN`` (least squares over N), and ``mixed`` (now ``planemap.first_pose:
mixed``): roll and pitch from ``cubic_fit6``, yaw and translation from
``quadratic_fit7`` (a smooth fit's roll and pitch miss the vehicle's sway; its yaw and
translation, which turn and shift the whole run in xy, carry less noise).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

# the walks' per-step errors
from handheld_walks import _errors

import planodom.odometry.planemap.midtime as midtime
from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import declared_sweep, world_for
from planodom.geometry import invert_transform
from planodom.metrics import ate
from planodom.odometry import run_odometry
from planodom.odometry.interpolate import curve_poses
from planodom.oracle import run_oracle
from planodom.se3 import se3_log
from planodom.simulation.random_world import simulate_world, world_fields

#: name -> (degree, nodes): the polynomial through (nodes = degree + 1) or the
#: least-squares one over the nodes nearest the first middle.
FITS = {"quadratic_fit": (2, 5), "quadratic": (2, 3), "cubic": (3, 4), "geodesic": (1, 2),
        "quadratic_fit7": (2, 7), "cubic_fit6": (3, 6), "cubic_fit8": (3, 8)}  # fmt: skip


def extrapolate(middles: np.ndarray, poses: np.ndarray, t: float, fit: str) -> np.ndarray:
    """``T_world_base`` (4, 4) at ``t`` s before the first of ``middles`` (N,) s on the
    curve ``fit`` (:data:`FITS`) through the ``poses`` (N, 4, 4) there."""
    if fit == "mixed":  # planemap.first_pose: mixed
        return midtime.first_pose(middles, poses, t, "mixed")
    degree, n = FITS[fit]
    if n > degree + 1:
        w = np.ones((len(middles), 6))
        return curve_poses(middles, poses, t, np.array([t]), degree, w, n)[0]
    return curve_poses(middles, poses, t, np.array([t]), degree)[0]


def _angle_deg(T: np.ndarray) -> float:
    return float(np.degrees(np.linalg.norm(se3_log(T)[:3])))


def capture(world_index: int, noise: float, epochs: int, oracle: bool) -> dict:
    """One run of the world as the experiment runs it, kept at the sweeps' middles."""
    world = world_for(world_index)
    full = simulate_world(world, noise, n_epochs=epochs, all_fields=True)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    o_rms = np.nan
    if oracle:
        orc = run_oracle(full.scans, full.times, world.trajectory, world.scene)
        o_rms = float(np.sqrt(np.mean(_errors(orc.poses, gt)[0] ** 2)))
    captured: list = []
    original = midtime.at_epoch_times

    def keep(run, epoch_times, order, first="quadratic_fit"):  # noqa: ANN001, ANN202
        captured.append((run, epoch_times, order))
        return original(run, epoch_times, order, first)

    midtime.at_epoch_times = keep  # run_odometry imports it when it runs
    try:
        run_odometry(world_fields(world, full), declared_sweep(world, PlanodomConfig()))
    finally:
        midtime.at_epoch_times = original
    run, epoch_times, order = captured[-1]
    middles = np.asarray(run.times, dtype=np.float64)
    return {"world": world_index, "noise": noise, "middles": middles, "poses": run.poses,
            "epoch_times": np.asarray(epoch_times), "order": order, "gt": gt,
            "M_true": world.trajectory.poses(middles), "T0_true": full.poses[0],
            "o_rms": o_rms}  # fmt: skip


def evaluate(c: dict) -> None:
    """Print one line per fit for a captured run ``c`` (:func:`capture`)."""
    middles, P, times, order = c["middles"], c["poses"], c["epoch_times"], int(c["order"])
    T = np.array([midtime._pose_at(middles, P, float(t), order) for t in times])
    head = f"world {int(c['world'])} {float(c['noise']) * 1000:g} mm"
    for fit in (*FITS, "mixed", "exact"):
        if fit == "exact":  # from the first middle by the true motion between them
            T[0] = P[0] @ invert_transform(c["M_true"][0]) @ c["T0_true"]
            bias = 0.0
        else:
            T[0] = extrapolate(middles, P, float(times[0]), fit)
            T0 = extrapolate(middles, c["M_true"], float(times[0]), fit)
            bias = _angle_deg(invert_transform(c["T0_true"]) @ T0)
        poses = invert_transform(T[0])[None] @ T
        rot, _ = _errors(poses, c["gt"])
        rms = float(np.sqrt(np.mean(rot**2)))
        a = ate(poses, c["gt"], align="origin", xy_only=True)["rmse"]
        print(f"{head} {fit:>14}: bias from true middles {bias:.5f} deg, step 1 {rot[0]:.5f}"
              f" deg, rotation {rms:.5f} ({rms / float(c['o_rms']):.1f}x), ATE "
              f"{1000 * a:.3f} mm", flush=True)  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("runs", nargs="*", help="world noise pairs")
    p.add_argument("--epochs", type=int, default=150)
    p.add_argument("--save", type=Path)
    p.add_argument("--load", nargs="*", type=Path, default=[])
    p.add_argument("--no-oracle", action="store_true")
    args = p.parse_args()
    for f in args.load:
        evaluate(dict(np.load(f)))
    for w, n in zip(args.runs[::2], args.runs[1::2], strict=True):
        c = capture(int(w), float(n), args.epochs, not args.no_oracle)
        if args.save:
            args.save.mkdir(parents=True, exist_ok=True)
            np.savez(args.save / f"{w}_{n}.npz", **c)
        evaluate(c)


if __name__ == "__main__":
    main()
