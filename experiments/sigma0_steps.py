"""Which steps of a built-in scene carry its heading error, by ingredient (issue 11, SIGMA0).

Per built-in scene and noise (``planodom run --scenario`` defaults, as
``builtin_scenes.py``; at sigma = 0 every step error is a model error) the odometry runs
as ``planodom run`` does (``--set`` overrides) and with the ingredients of
:mod:`rig2d_ingredients` swapped in: ``true-deskew`` (every scan deskewed with the true
motion, given as deskewed), and ``+osolve`` / ``+labels+osolve`` (the oracle's solve over
the planes and associations the run committed, or over the same planes grouped by their
true surface). Per variant: ATE xy (origin), the steps' summed yaw error (deg: the lap's
heading error), rotation / xy rms, unresolved and degenerate counts; then the steps whose
yaw error is largest in the run (``--top``), each with its status, reference epoch and
every variant's yaw error (mdeg) there, and the stretches (``--window`` epochs) whose
summed yaw error is largest. ``--npz`` saves every variant's per-step yaw / xy errors and
statuses.

    uv run python experiments/sigma0_steps.py --scene random-outdoor --noise 0
    uv run python experiments/sigma0_steps.py --scene random-outdoor --noise 0 \\
        --set extraction.gap_bridge=predicted --variants planodom
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np
from builtin_scenes import config_with, simulated, true_twist
from builtin_unresolved import step_yaw_errors
from rig2d_ingredients import Committed, oracle_solve, recording

from planodom.metrics import ate, per_epoch_errors, relative_motions
from planodom.odometry.deskewed_epochs import Deskewed
from planodom.odometry.run import run_odometry, with_motion_bounds
from planodom.oracle import deskewed_points

VARIANTS = ("planodom", "planodom+osolve", "true-deskew", "true-deskew+osolve",
            "true-deskew+labels+osolve")  # fmt: skip


def step_errors(poses: np.ndarray, gt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(E,) each step's yaw error (deg) and xy error (m), 0 for the first epoch."""
    err = per_epoch_errors(relative_motions(poses), relative_motions(gt))
    xy = np.concatenate([[0.0], np.hypot(err["x"], err["y"])])
    return step_yaw_errors(poses, gt), xy


def run_variants(
    scene: str, noise: str, sets: list[str], names: list[str], epochs: int | None = None
) -> dict:
    """Per variant: (poses, statuses, prevs, twists) of the scene's first ``epochs``
    (module docstring); ``twists`` (E, 6) each epoch's deskewing twist (nan: none)."""
    sim, gt = simulated(scene, noise)
    n = len(sim.times) if epochs is None else epochs
    gt = gt[:n]
    config = config_with(sets)
    bounds_cfg = with_motion_bounds(config, sim.rig.motion_bounds).association
    bounds = (float(np.radians(bounds_cfg.max_rotation_deg)), bounds_cfg.max_translation_m)
    true = np.array([true_twist(sim, k) for k in range(n)])
    out: dict[str, tuple] = {"truth": (gt, None, None, true)}
    for base in ("planodom", "true-deskew"):
        if not any(n.startswith(base) for n in names):
            continue
        log: list[Committed] = []
        if base == "planodom":
            source = list(sim.scans[:n])
        else:
            source = [Deskewed(s, replace(s, points=deskewed_points(s, sim.trajectory, float(t))))
                      for s, t in zip(sim.scans[:n], sim.times[:n], strict=True)]  # fmt: skip
        with recording(log, force_given=base == "true-deskew"):
            run = run_odometry(source, config, sim.rig, times=sim.times[:n])
        prevs = [None] + [c.relative.prev for c in log[1:]]  # type: ignore[attr-defined]
        twists = np.array([np.full(6, np.nan) if c.twist is None else c.twist for c in log])
        out[base] = (run.poses, list(run.statuses), prevs, twists)
        for labels in (False, True):
            key = f"{base}+labels+osolve" if labels else f"{base}+osolve"
            if key in names:
                poses, st = oracle_solve(log, sim.times, sim.poses, sim.scene, labels, bounds)
                out[key] = (poses, st, prevs, None)
    return out


def report(out: dict, top: int, window: int) -> None:
    gt = out["truth"][0]
    names = [n for n in out if n != "truth"]
    errs = {n: step_errors(out[n][0], gt) for n in names}
    for n in names:
        yaw, xy = errs[n]
        st = np.array(out[n][1])
        print(f"{n:26s} ATE xy {ate(out[n][0], gt, 'origin', xy_only=True)['rmse']:.4f} m  "
              f"sum yaw {yaw.sum():+.4f} deg  yaw rms {np.sqrt(np.mean(yaw**2)):.4f} deg  "
              f"xy rms {np.sqrt(np.mean(xy**2)) * 100:.3f} cm  unresolved "
              f"{(st == 'unresolved').sum()} degenerate {(st == 'degenerate').sum()}")  # fmt: skip
    yaw0 = errs[names[0]][0]
    st0, prev0 = out[names[0]][1], out[names[0]][2]
    print(f"\nsteps with the largest |yaw error| of {names[0]} (mdeg):")
    print("   k status      prev " + " ".join(f"{n[:18]:>18s}" for n in names))
    tw0, true = out[names[0]][3], out["truth"][3]
    for k in sorted(np.argsort(-np.abs(yaw0))[:top]):
        print(f"{k:4d} {st0[k][:11]:11s} {prev0[k]!s:>4s} "
              + " ".join(f"{errs[n][0][k] * 1e3:18.2f}" for n in names)
              + (f"  yaw rate used {np.degrees(tw0[k][2]):+.3f} true {np.degrees(true[k][2]):+.3f}"
                 f" deg/s, speed used {np.linalg.norm(tw0[k][3:]):.3f} true "
                 f"{np.linalg.norm(true[k][3:]):.3f} m/s" if tw0 is not None else ""))  # fmt: skip
    print(f"\n{window}-epoch stretches, summed yaw error (deg), largest |sum| of {names[0]}:")
    sums = {n: np.convolve(errs[n][0], np.ones(window), "valid") for n in names}
    starts = np.arange(0, len(yaw0) - window + 1, window)
    order = starts[np.argsort(-np.abs(sums[names[0]][starts]))][:top]
    for s in sorted(order):
        short = [x[:3] for x in st0[s : s + window]]
        bad = sum(x != "ok" for x in st0[s : s + window])
        print(f"{s:4d}-{s + window - 1:4d} " + " ".join(f"{sums[n][s]:+9.4f}" for n in names)
              + f"  not ok {bad} {' '.join(sorted(set(short)))}")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="random-outdoor")
    ap.add_argument("--noise", default="0")
    ap.add_argument(
        "--set", nargs="*", action="extend", default=[], help="config overrides key=value"
    )
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--top", type=int, default=20)
    ap.add_argument("--window", type=int, default=20)
    ap.add_argument("--npz", default=None, help="save per-step errors and statuses")
    ap.add_argument("--epochs", type=int, default=None, help="the first N epochs (default all)")
    args = ap.parse_args()
    out = run_variants(args.scene, args.noise, args.set, args.variants.split(","), args.epochs)
    if args.npz:
        gt = out["truth"][0]
        saved: dict[str, np.ndarray] = {}
        for n in out:
            saved[f"{n}:poses"] = out[n][0]
            if out[n][3] is not None:
                saved[f"{n}:twists"] = out[n][3]
            if n != "truth":
                saved[f"{n}:yaw"], saved[f"{n}:xy"] = step_errors(out[n][0], gt)
                saved[f"{n}:status"] = np.array(out[n][1])
        np.savez(args.npz, **saved)  # type: ignore[arg-type]
    report(out, args.top, args.window)


if __name__ == "__main__":
    main()
