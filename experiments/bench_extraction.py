"""Extraction speed: epochs per second of ``extract`` for the 2D rig and a 32-beam lidar.

Simulates the paper loop once per rig (continuous motion, 6 mm noise; the 2D rig also
with a constant-velocity deskew twist), then times ``extract`` alone on one thread
(BLAS / OpenMP pinned to 1). Prints wall-clock and CPU-time rates: on a shared machine
the CPU-time rate is the one to compare.

    uv run python experiments/bench_extraction.py
    uv run python experiments/bench_extraction.py --epochs 100 --lidar-epochs 20
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
from planodom.geometry import invert_transform, se3_log  # noqa: E402
from planodom.simulation import simulate_named  # noqa: E402


def _twists(run) -> list[np.ndarray]:
    dt = 1.0 / run.epoch_rate
    out = []
    for t_k in run.times:
        T0, T1 = run.trajectory.poses(np.array([t_k, t_k + dt]))
        out.append(se3_log(invert_transform(T0) @ T1) / dt)
    return out


def bench(run, twists, repeat: int) -> tuple[float, float, float]:
    """(wall ep/s, cpu ep/s, points per epoch), best of ``repeat`` passes."""
    cfg = ExtractionConfig(range_noise_m=0.006)
    for k, scan in enumerate(run.scans[:3]):  # warm-up (imports, caches)
        extract(scan, cfg, twist=None if twists is None else twists[k])
    best_wall = best_cpu = 0.0
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        for k, scan in enumerate(run.scans):
            extract(scan, cfg, twist=None if twists is None else twists[k])
        w, c = time.perf_counter() - w0, time.process_time() - c0
        best_wall = max(best_wall, len(run) / w)
        best_cpu = max(best_cpu, len(run) / c)
    return best_wall, best_cpu, float(np.mean([len(s) for s in run.scans]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--epochs", type=int, default=100)
    ap.add_argument("--lidar-epochs", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    print(f"{'case':40s} {'pts/ep':>8s} {'wall ep/s':>10s} {'cpu ep/s':>9s}  target")
    rigs = (("isoclinal", args.epochs, 500), ("lidar32", args.lidar_epochs, 20))
    for rig, n, target in rigs:
        run = simulate_named("paper-loop", rig, noise=0.006, seed=1, n_epochs=n)
        cases = [("no deskew", None), ("cv-deskew", _twists(run))]
        for name, tw in cases if rig == "isoclinal" else cases[1:]:
            wall, cpu, npts = bench(run, tw, args.repeat)
            print(f"{rig + ' 6mm ' + name:40s} {npts:8.0f} {wall:10.0f} {cpu:9.0f}  >= {target}")


if __name__ == "__main__":
    main()
