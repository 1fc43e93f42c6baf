"""Benchmark the odometry front end: epochs per second on one core.

Simulates the default paper loop with the isoclinal 2D rig (sigma = 6 mm, snapshot), then
times, over all epochs, (a) plane extraction, (b) association + consensus + chaining
(``PlaneOdometry.register_planes``) and (c) both together, the front end of the issue's
target (>= 200 epochs/s). Threads of numpy's BLAS are limited to one and the process is
pinned to one CPU when the platform allows. Run:
``uv run python experiments/bench_odometry.py [--epochs N] [--noise SIGMA] [--pipeline P]``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402

from planodom.config import PlanodomConfig  # noqa: E402
from planodom.extraction import extract_planes  # noqa: E402
from planodom.odometry import PlaneOdometry  # noqa: E402
from planodom.simulation import simulate_named  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--epochs", type=int, default=300)
    parser.add_argument("--noise", type=float, default=0.006)
    parser.add_argument("--pipeline", default="wocsc")
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})

    sim = simulate_named("paper-loop", "isoclinal", noise=args.noise, seed=1,
                         n_epochs=args.epochs, motion="snapshot")  # fmt: skip
    cfg = PlanodomConfig()
    cfg.odometry.pipeline = args.pipeline
    extract_planes(sim[0], cfg.extraction)  # warm-up (imports, caches)

    t0 = time.perf_counter()
    planes = [extract_planes(scan, cfg.extraction) for scan in sim]
    t_extract = time.perf_counter() - t0

    odo = PlaneOdometry(cfg)
    t0 = time.perf_counter()
    for p, t in zip(planes, sim.times, strict=True):
        odo.register_planes(p, t)
    t_odo = time.perf_counter() - t0

    n = len(sim)
    print(f"paper loop, isoclinal rig, sigma = {args.noise * 1000:g} mm, {n} epochs, "
          f"pipeline {args.pipeline}, {sum(map(len, planes)) / n:.1f} planes/epoch")  # fmt: skip
    print(f"extraction          : {n / t_extract:8.1f} epochs/s ({1e3 * t_extract / n:.2f} ms)")
    print(f"association+consensus: {n / t_odo:8.1f} epochs/s ({1e3 * t_odo / n:.2f} ms)")
    total = t_extract + t_odo
    print(f"front end           : {n / total:8.1f} epochs/s (target >= 200)")


if __name__ == "__main__":
    main()
