"""How honest the streaming odometry's chained pose covariances are across its
constant-velocity bridges (``covariances.npz`` key ``chained``).

For each world and range noise, the 2D rig's odometry is run over ``--epochs`` epochs
(the smoothing's odometry config, as ``planodom experiment loops``) and its relative
covariances chained into pose covariances three ways
(:func:`planodom.covariances.chained_covariances`, ``velocity``): ``none`` (every step
independent), ``measured`` (default: a bridged run shares the error of the last ok step's
velocity, on top of its steps' own terms) and ``stated`` (the bridged steps' stated sigma
taken as one shared velocity error). Per world and model: mean and median NEES5 of the
poses against the truth (chi2(5); body z left out), and of the horizontal position alone
(NEES2, chi2(2)); per bridged run of ``--min-run`` or more epochs: its error along its
bridged direction (that of the largest variance of its first step) over the sigma along
it of the covariance chained over the run alone (:func:`run_z`), ``z``, under each model.

    uv run python experiments/odometry_chain.py --worlds 0,2,6,14,18,32 --levels 0.02 -o OUT.csv
"""

from __future__ import annotations

import argparse
from typing import Literal

import numpy as np

from planodom.config import PlanodomConfig
from planodom.covariances import chained_covariances, odometry_covariances
from planodom.experiments.generalisation import world_for
from planodom.geometry import invert_transform
from planodom.metrics import pose_nees
from planodom.odometry import run_odometry
from planodom.results import write_rows
from planodom.simulation.random_world import simulate_world, world_fields
from planodom.smoothing.run import smoothing_config

MODES: tuple[Literal["none", "measured", "stated"], ...] = ("none", "measured", "stated")


def bridged_runs(status: np.ndarray, min_run: int) -> list[tuple[int, int]]:
    """(first, last) epochs of each run of ``min_run`` or more consecutive steps that are
    not "ok" (status (E,) as in ``covariances.npz``)."""
    runs, k, n = [], 1, len(status)
    while k < n:
        if status[k] == "ok":
            k += 1
            continue
        a = k
        while k < n and status[k] != "ok":
            k += 1
        if k - a >= min_run:
            runs.append((a, k - 1))
    return runs


def run_z(
    poses: np.ndarray,
    truth: np.ndarray,
    arrays: dict[str, np.ndarray],
    run: tuple[int, int],
    sigma_m: float,
    velocity: Literal["none", "measured", "stated"],
) -> float:
    """The run's horizontal error, from the epoch j two before it (so that the ok step
    into it, whose velocity the bridge carries, is in) to its last, along its bridged
    direction (the largest variance of its first step's), over the sigma along it of the
    covariance chained over the same epochs alone."""
    a, b = run
    j = max(a - 2, 0)
    part = slice(j, b + 1)
    local = invert_transform(poses[j]) @ poses[part]
    status = arrays["relative_status"][part].copy()
    status[0] = "first"
    prev = arrays["relative_prev"][part] - j
    prev[0] = -1
    cov = chained_covariances(
        local, arrays["times"][part], arrays["relative"][part], prev, status, sigma_m, velocity
    )
    R = local[-1][:3, :3]  # the last pose's translation covariance, in frame j
    P = (R @ cov[-1][3:, 3:] @ R.T)[:2, :2]
    err = local[-1][:2, 3] - (invert_transform(truth[j]) @ truth[b])[:2, 3]
    v = local[a - 1 - j][:2, :2] @ np.linalg.eigh(arrays["relative"][a][3:, 3:])[1][:, -1]
    return float(abs(err @ v) / np.sqrt(v @ P @ v))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worlds", default="0,2,6,14,18,32")
    ap.add_argument("--levels", default="0.02", help="range noise sigmas, m")
    ap.add_argument("--epochs", type=int, default=200)
    ap.add_argument("--min-run", type=int, default=10)
    ap.add_argument("--own-scan-plane", default="kept", help="extraction.own_scan_plane")
    ap.add_argument("-o", "--out", required=True, help="CSV, one row per world and model")
    args = ap.parse_args()
    config = PlanodomConfig().updated(
        {"extraction.own_scan_plane": args.own_scan_plane}, source="--own-scan-plane"
    )
    rows = []
    for w in (int(x) for x in args.worlds.split(",")):
        for noise in (float(x) for x in args.levels.split(",")):
            world = world_for(w)
            full = simulate_world(world, noise, n_epochs=args.epochs, all_fields=True)
            truth = invert_transform(full.poses[0])[None] @ full.poses
            odo = run_odometry(world_fields(world, full), smoothing_config(config))
            arr = odometry_covariances(odo)
            sigma = config.odometry.refine_max_sigma_m
            runs = bridged_runs(arr["relative_status"], args.min_run)
            for mode in MODES:
                cov = chained_covariances(
                    odo.poses, arr["times"], arr["relative"], arr["relative_prev"],
                    arr["relative_status"], sigma, velocity=mode,
                )  # fmt: skip
                n5 = pose_nees(odo.poses[1:], cov[1:], truth[1:], range(5))
                n2 = pose_nees(odo.poses[1:], cov[1:], truth[1:], [3, 4])
                zs = [run_z(odo.poses, truth, arr, r, sigma, mode) for r in runs]
                row = {
                    "world": w, "noise_m": noise, "model": mode,
                    "nees5_mean": float(np.nanmean(n5)), "nees5_median": float(np.nanmedian(n5)),
                    "nees2_mean": float(np.nanmean(n2)), "nees2_median": float(np.nanmedian(n2)),
                    "runs": " ".join(f"{a}-{b}" for a, b in runs),
                    "run_z": " ".join(f"{z:.2f}" for z in zs),
                }  # fmt: skip
                rows.append(row)
                print(row, flush=True)
    write_rows(args.out, rows)


if __name__ == "__main__":
    main()
