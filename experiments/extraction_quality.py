"""Plane extraction quality on the simulated paper loop (issue 3).

For the paper's noise levels (0, 6 mm, 2 cm, 10 cm) and both rigs (the isoclinal 2D rig,
a 32-beam lidar) prints per noise level:

- recall: walls the epoch's points determine (two crossing traces of two rings per the
  labels, :func:`planodom.simulation.epoch_observability`, 10 deg) found as a plane
  that matches them (within the tolerances) and holds at least half of their points
  (coplanar walls with a narrow gap between them are one plane, which finds both);
- precision: extracted planes whose ``truth_id`` surface matches within the tolerances
  (angle ``--tol-deg``, offset ``--tol-m``; ground included);
- normal error (deg) and offset error (m) of every plane against its truth_id surface,
  median and 95th percentile;
- epochs per second of ``extract`` alone, one thread (BLAS / OpenMP pinned to 1).

The noise-free row of the 2D rig is run with ``motion="snapshot"``; the motion rows
(continuous motion at sigma = 0) show the error with no deskew, with a constant-velocity
twist from ground truth (``log(T_k^-1 T_k+1) * rate``, the best constant twist of the
epoch; the loop's sway makes it inexact), and, on a constant-twist trajectory, with the
true twist (exact). The 2D rig's noisy rows are also run without a twist ("no-deskew":
the odometry's first epochs), where the extractor works in time windows
(``ExtractionConfig.time_windows``).

    uv run python experiments/extraction_quality.py            # full table (~1 min)
    uv run python experiments/extraction_quality.py --epochs 40 --lidar-epochs 10
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from planodom.config import ExtractionConfig  # noqa: E402
from planodom.extraction import extract  # noqa: E402
from planodom.geometry import invert_transform, se3_log, transform_planes  # noqa: E402
from planodom.simulation import (  # noqa: E402
    TwistTrajectory,
    epoch_observability,
    simulate_named,
)

NOISES = (0.0, 0.006, 0.02, 0.1)


def true_planes(run, k: int) -> dict[int, tuple[np.ndarray, float]]:
    """Every surface's (n, d) in the base frame at epoch k's reference time."""
    T_base_world = invert_transform(run.poses[k])
    n, d = transform_planes(T_base_world, run.scene.normals, run.scene.offsets)
    return {int(i): (n[j], float(d[j])) for j, i in enumerate(run.scene.ids)}


def plane_errors(plane, truth) -> tuple[float, float]:
    """Unoriented normal error (deg) and offset error (m) of a plane against (n, d)."""
    n, d = truth
    s = 1.0 if plane.normal @ n >= 0 else -1.0
    ang = np.degrees(np.arctan2(np.linalg.norm(np.cross(plane.normal, n)), abs(plane.normal @ n)))
    return float(ang), float(abs(plane.offset - s * d))


def evaluate(run, config: ExtractionConfig, twists=None, tol_deg=3.0, tol_m=0.15) -> dict:
    """Recall, precision, errors and speed of ``extract`` over the epochs of ``run``."""
    found = determinable = n_planes = n_good = 0
    ang_err, off_err = [], []
    elapsed = 0.0
    if len(run):  # warm-up: the first call loads (or compiles) the numba kernels
        extract(run.scans[0], config, twist=None if twists is None else twists[0])
    for k, scan in enumerate(run.scans):
        xi = None if twists is None else twists[k]
        t0 = time.perf_counter()
        res = extract(scan, config, twist=xi)
        elapsed += time.perf_counter() - t0
        truth = true_planes(run, k)
        good_ids = set()
        wall_points = (
            np.bincount(scan.label[scan.label >= 0])
            if scan.label is not None
            else np.zeros(0, dtype=int)
        )
        for p, idx in zip(res.planes, res.inliers, strict=True):
            n_planes += 1
            if p.truth_id < 0:
                continue
            a, o = plane_errors(p, truth[p.truth_id])
            ang_err.append(a)
            off_err.append(o)
            if a <= tol_deg and o <= tol_m:
                n_good += 1
                good_ids.add(p.truth_id)
            # It also finds other walls whose true plane it matches and of which it holds
            # at least half the epoch's points (coplanar walls apart by a gap narrower
            # than plane_gap_m are one plane, which finds both).
            labs, cnt = np.unique(scan.label[idx], return_counts=True)
            for lab, c in zip(labs, cnt, strict=True):
                if lab < 0 or 2 * c < wall_points[lab]:
                    continue
                a, o = plane_errors(p, truth[int(lab)])
                if a <= tol_deg and o <= tol_m:
                    good_ids.add(int(lab))
        if scan.ring is not None and len(np.unique(scan.ring)) <= config.max_rig_rings:
            obs = set(epoch_observability(scan, run.scene).walls_observable)
        else:  # a lidar: every wall with enough points is determined
            ids, cnt = np.unique(scan.label[scan.label >= 0], return_counts=True)
            walls = {int(s.id) for s in run.scene.surfaces if s.kind in ("wall", "facade")}
            obs = {int(i) for i, c in zip(ids, cnt, strict=True) if c >= 200 and int(i) in walls}
        determinable += len(obs)
        found += len(obs & good_ids)
    ang = np.array(ang_err) if ang_err else np.array([np.nan])
    off = np.array(off_err) if off_err else np.array([np.nan])
    return {
        "recall": found / max(determinable, 1),
        "precision": n_good / max(n_planes, 1),
        "planes/epoch": n_planes / max(len(run), 1),
        "ang_med": float(np.median(ang)),
        "ang_p95": float(np.percentile(ang, 95)),
        "off_med": float(np.median(off)),
        "off_p95": float(np.percentile(off, 95)),
        "max_ang": float(np.max(ang)),
        "max_off": float(np.max(off)),
        "eps": len(run) / elapsed,
    }


def gt_twists(run) -> list[np.ndarray]:
    """Constant-velocity twist of each epoch from ground truth: log(T_k^-1 T_k+dt) / dt."""
    dt = 1.0 / run.epoch_rate
    out = []
    for t_k in run.times:
        T0, T1 = run.trajectory.poses(np.array([t_k, t_k + dt]))
        out.append(se3_log(invert_transform(T0) @ T1) / dt)
    return out


HEADER = (
    f"{'case':34s} {'recall':>7s} {'prec':>7s} {'pl/ep':>6s} {'ang med':>9s} {'ang p95':>9s}"
    f" {'off med':>9s} {'off p95':>9s} {'ep/s':>7s}"
)


def row(name: str, r: dict) -> str:
    return (
        f"{name:34s} {100 * r['recall']:6.1f}% {100 * r['precision']:6.1f}% "
        f"{r['planes/epoch']:6.1f} {r['ang_med']:9.2e} {r['ang_p95']:9.2e} "
        f"{r['off_med']:9.2e} {r['off_p95']:9.2e} {r['eps']:7.0f}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--epochs", type=int, default=None, help="2D-rig epochs (default: a lap)")
    ap.add_argument("--lidar-epochs", type=int, default=60)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--tol-deg", type=float, default=3.0)
    ap.add_argument("--tol-m", type=float, default=0.15)
    args = ap.parse_args()
    tol = {"tol_deg": args.tol_deg, "tol_m": args.tol_m}
    print(f"match tolerances: {args.tol_deg} deg, {args.tol_m} m; normal errors in deg")
    print(HEADER)
    for rig, n_ep in (("isoclinal", args.epochs), ("lidar32", args.lidar_epochs)):
        for sigma in NOISES:
            motion = "snapshot" if sigma == 0.0 else "continuous"
            run = simulate_named(
                "paper-loop", rig, noise=sigma, seed=args.seed, n_epochs=n_ep, motion=motion
            )
            cfg = ExtractionConfig(range_noise_m=max(sigma, 0.002))
            twists = None if motion == "snapshot" else gt_twists(run)
            name = f"{rig} sigma={sigma * 1000:g}mm {motion}"
            if twists is not None:
                name += " cv-deskew"
            print(row(name, evaluate(run, cfg, twists, **tol)), flush=True)
            if twists is not None and rig == "isoclinal":  # bootstrap: no twist yet
                name = f"{rig} sigma={sigma * 1000:g}mm {motion} no-deskew"
                print(row(name, evaluate(run, cfg, None, **tol)), flush=True)
        # Motion at sigma = 0: no deskew, constant-velocity deskew, exact constant twist.
        run = simulate_named("paper-loop", rig, noise=0.0, seed=args.seed, n_epochs=n_ep)
        cfg = ExtractionConfig(range_noise_m=0.002)
        print(row(f"{rig} sigma=0 continuous no-deskew", evaluate(run, cfg, None, **tol)))
        print(row(f"{rig} sigma=0 continuous cv-deskew", evaluate(run, cfg, gt_twists(run), **tol)))
        xi = np.array([0.02, -0.03, 0.25, 2.0, 0.1, 0.05])
        traj = TwistTrajectory(run.poses[0], xi, duration=4.0)
        run = simulate_named("paper-loop", rig, noise=0.0, seed=args.seed, trajectory=traj)
        r = evaluate(run, cfg, [xi] * len(run), **tol)
        print(row(f"{rig} sigma=0 const-twist true-deskew", r))
        print(
            f"    (max normal error {r['max_ang']:.2e} deg, max offset error {r['max_off']:.2e} m)"
        )


if __name__ == "__main__":
    main()
