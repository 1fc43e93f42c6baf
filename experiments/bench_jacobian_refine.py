"""CPU time of the Jacobian refinement (``jacobian_refine.py``) against the default and
KISS-ICP, on the same simulated runs, in one process.

Per world: the run is simulated once and given to planodom's default odometry, to the
odometry with the refinement by the planes' deskewing Jacobians (compiled Jacobians,
``jacobian_refine.py --compiled``) and to KISS-ICP (as ``bench_rig2d_vs_kiss.py`` runs
it), in turn, ``--reps`` times after an untimed warm-up; the fastest repetition of each
counts (process time). Prints CPU ms an epoch, the ratios to KISS-ICP (planodom's
epochs/s as a multiple of KISS-ICP's) and the extractions an epoch of each.

    uv run --extra baselines python experiments/bench_jacobian_refine.py --noise 0.02 \\
        --epochs 150 --worlds 160 162 166 168 172 180 184 188 192 196
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402
from collections import defaultdict  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

# the scripts beside this one in experiments/
from bench_rig2d_stages import instrument  # noqa: E402
from jacobian_refine import compiled_jacobian, patch_refinement  # noqa: E402

import planodom.extraction.planes.builder as builder_mod  # noqa: E402
import planodom.odometry.odometry as odo_mod  # noqa: E402
from planodom.config import PlanodomConfig  # noqa: E402
from planodom.experiments.generalisation import declared_sweep, world_for  # noqa: E402
from planodom.experiments.peers import kiss_icp_poses  # noqa: E402
from planodom.odometry import run_odometry  # noqa: E402
from planodom.simulation.random_world import simulate_world, world_fields  # noqa: E402

COUNTED = (("planodom.extraction.pipeline", "rig2d_planes", "extractions"),)


def switch() -> tuple[Any, Any]:
    """The refinement's two versions: (default, Jacobian) ``_estimate_scan``, and the
    builder's Jacobian functions (numpy, compiled) in the same order, patched once."""
    default_scan, default_jac = odo_mod.PlaneOdometry._estimate_scan, builder_mod.deskew_jacobian
    patch_refinement(defaultdict(int))
    jac_scan = odo_mod.PlaneOdometry._estimate_scan
    odo_mod.PlaneOdometry._estimate_scan = default_scan  # type: ignore[method-assign]
    return (default_scan, jac_scan), (default_jac, compiled_jacobian)


def one_world(w: int, noise: float, epochs: int, reps: int, n: defaultdict[str, int]) -> dict:
    """CPU ms an epoch of default, Jacobian and KISS-ICP, and extractions an epoch."""
    scans, jacs = SWITCH
    world = world_for(w)
    cfg = declared_sweep(world, PlanodomConfig())
    cfg_j = cfg.updated({"extraction.deskew_jacobian": True}, source="bench")
    run = world_fields(world, simulate_world(world, noise, n_epochs=epochs, all_fields=True))
    warm = world_fields(world, simulate_world(world, 0.0, n_epochs=3, all_fields=True))
    max_range = max(s.max_range for s in world.sensor_rig.sensors)
    period = 1.0 / world.epoch_rate
    out: dict[str, Any] = {"world": w, "points": float(np.mean([len(s) for s in run.scans]))}
    cpu: defaultdict[str, list[float]] = defaultdict(list)
    for rep in range(reps + 1):
        for name, c, k in (("default", cfg, 0), ("jacobian", cfg_j, 1)):
            odo_mod.PlaneOdometry._estimate_scan = scans[k]  # type: ignore[method-assign]
            builder_mod.deskew_jacobian = jacs[k]
            n.clear()
            c0 = time.process_time()
            run_odometry(warm if rep == 0 else run, c)
            if rep:
                cpu[name].append(time.process_time() - c0)
                out[f"{name}_extractions"] = n["extractions"] / epochs
        c0 = time.process_time()
        kiss_icp_poses(warm.scans if rep == 0 else run.scans, period, max_range)
        if rep:
            cpu["kiss"].append(time.process_time() - c0)
    for name, times in cpu.items():
        out[f"{name}_ms"] = 1e3 * min(times) / epochs
    return out


SWITCH: tuple[Any, Any] = ((), ())


def main() -> None:
    global SWITCH
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--worlds", type=int, nargs="+", default=[160, 162, 168])
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--reps", type=int, default=2)
    args = ap.parse_args()
    SWITCH = switch()
    n: defaultdict[str, int] = defaultdict(int)
    instrument(defaultdict(float), n, COUNTED)
    print(f"{args.noise * 1e3:g} mm, {args.epochs} epochs, CPU ms an epoch (best of {args.reps})")
    for w in args.worlds:
        r = one_world(w, args.noise, args.epochs, args.reps, n)
        print(
            f"world {w:3d} {r['points']:6.0f} points | default {r['default_ms']:6.2f} "
            f"jacobian {r['jacobian_ms']:6.2f} KISS-ICP {r['kiss_ms']:6.2f} | ratio "
            f"{r['kiss_ms'] / r['default_ms']:4.2f} -> {r['kiss_ms'] / r['jacobian_ms']:4.2f} | "
            f"extractions {r['default_extractions']:.2f} -> {r['jacobian_extractions']:.2f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
