"""The 2D rig's speed against KISS-ICP, in CPU time, on the same simulated runs.

``planodom experiment generalisation`` reports epochs/s from wall time, on a machine
whose load moves wall time by more than the methods differ. Here each world's run is
simulated once and given to planodom's default odometry and to KISS-ICP (as the
experiment runs it: one thread, voxel ``max_range / 100``), alternating, ``--reps``
times each after an untimed warm-up on the world's first epochs; the fastest repetition
of each counts (process time). Per world: points an epoch, both methods' CPU ms an
epoch and their ratio (KISS-ICP's time over planodom's: planodom's epochs/s as a
multiple of KISS-ICP's), planodom's extractions, relative poses and solves an epoch
(counted around the functions the stage bench times, ``bench_rig2d_stages.py``) and its
degenerate and unresolved epochs; then the median ratio per block of worlds.
``--deskew-iterations 0`` times planodom without the deskewing's refinement passes (a
what-if of the speed one pass an epoch would give, not a setting measured for accuracy).

    uv run --extra baselines python experiments/bench_rig2d_vs_kiss.py --noise 0.02 \\
        --epochs 150 --worlds 0 2 4 6 8 10 12 14 16 18 140 142 144 146 148
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402
from collections import defaultdict  # noqa: E402

import numpy as np  # noqa: E402

# the stage bench's wrappers (this script runs beside it in experiments/)
from bench_rig2d_stages import instrument  # noqa: E402

from planodom.config import PlanodomConfig  # noqa: E402
from planodom.experiments.generalisation import declared_sweep, world_for  # noqa: E402
from planodom.experiments.peers import kiss_available, kiss_icp_poses  # noqa: E402
from planodom.odometry import run_odometry  # noqa: E402
from planodom.simulation.random_world import simulate_world, world_fields  # noqa: E402

#: (module, name, counter): the calls counted, wrapped by the stage bench's ``instrument``
#: (its per-call timer costs microseconds against milliseconds an epoch).
COUNTED = (
    ("planodom.extraction.pipeline", "rig2d_planes", "extractions"),
    ("planodom.odometry.odometry", "estimate_relative_pose", "poses"),
    ("planodom.odometry.solver", "_solve", "solves"),
)


def one_world(
    w: int, noise: float, epochs: int, reps: int, n: defaultdict[str, int],
    deskew_iterations: int | None = None,
) -> dict:  # fmt: skip
    """The figures of world ``w`` (module docstring); ``deskew_iterations``: that
    ``odometry.deskew_iterations`` instead of the default (a what-if of fewer passes)."""
    world = world_for(w)
    cfg = declared_sweep(world, PlanodomConfig())
    if deskew_iterations is not None:
        odo_cfg = cfg.odometry.model_copy(update={"deskew_iterations": deskew_iterations})
        cfg = cfg.model_copy(update={"odometry": odo_cfg})
    run = world_fields(world, simulate_world(world, noise, n_epochs=epochs, all_fields=True))
    warm = world_fields(world, simulate_world(world, 0.0, n_epochs=3, all_fields=True))
    max_range = max(s.max_range for s in world.sensor_rig.sensors)
    period = 1.0 / world.epoch_rate
    run_odometry(warm, cfg)
    kiss_icp_poses(warm.scans, period, max_range)
    cpu_p, cpu_k = [], []
    for _ in range(reps):
        n.clear()
        c0 = time.process_time()
        odo = run_odometry(run, cfg)
        cpu_p.append(time.process_time() - c0)
        c0 = time.process_time()
        kiss_icp_poses(run.scans, period, max_range)
        cpu_k.append(time.process_time() - c0)
    statuses = odo.statuses
    return {
        "world": w, "kind": world.kind, "points": float(np.mean([len(s) for s in run.scans])),
        "planodom_ms": 1e3 * min(cpu_p) / epochs, "kiss_ms": 1e3 * min(cpu_k) / epochs,
        **{key: n[key] / epochs for _, _, key in COUNTED},
        "degenerate": statuses.count("degenerate") / epochs,
        "unresolved": statuses.count("unresolved") / epochs,
    }  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--worlds", type=int, nargs="+", default=[0, 2, 4, 140, 142, 144])
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--reps", type=int, default=2)
    ap.add_argument(
        "--deskew-iterations", type=int, default=None,
        help="odometry.deskew_iterations for planodom (default: the config's)",
    )  # fmt: skip
    args = ap.parse_args()
    if not kiss_available():
        raise SystemExit("KISS-ICP is not installed: uv sync --extra baselines")
    if any(w % 2 for w in args.worlds):
        raise SystemExit("the 2D rig's worlds are the even ones")
    n: defaultdict[str, int] = defaultdict(int)
    instrument(defaultdict(float), n, COUNTED)
    blocks: defaultdict[int, list[float]] = defaultdict(list)
    print(f"{args.noise * 1e3:g} mm, {args.epochs} epochs, CPU ms an epoch (best of {args.reps})")
    for w in args.worlds:
        r = one_world(w, args.noise, args.epochs, args.reps, n, args.deskew_iterations)
        ratio = r["kiss_ms"] / r["planodom_ms"]
        blocks[w // 20].append(ratio)
        print(
            f"world {w:3d} {r['kind']:7s} {r['points']:6.0f} points | planodom "
            f"{r['planodom_ms']:6.2f} KISS-ICP {r['kiss_ms']:6.2f} ratio {ratio:4.2f} | "
            f"extractions {r['extractions']:.2f} poses {r['poses']:.2f} solves "
            f"{r['solves']:.2f} | degenerate {r['degenerate']:.2f} unresolved "
            f"{r['unresolved']:.2f}",
            flush=True,
        )
    for b, ratios in sorted(blocks.items()):
        print(f"worlds {20 * b}-{20 * b + 19}: median ratio {np.median(ratios):.2f} "
              f"({len(ratios)} worlds)")  # fmt: skip


if __name__ == "__main__":
    main()
