"""Benchmark the simulator: rays per second and milliseconds per epoch.

(a) the isoclinal 2D rig (4 scanners x 361 beams x 7-8 sweeps, about 10.8k rays) against
    ~100 polygons (``random_walls(100)``), target < 2 ms per epoch;
(b) one 32 x 1024 lidar sweep (32768 rays) against the same scene, target < 5 ms.

"epoch" is the whole :meth:`Simulator.epoch` (a pose for every firing, world rays, Embree,
float64 refinement, noise, points, Scan); "cast" is :meth:`RayCaster.cast_rays` alone on
the same rays. Wall-clock times are medians (and minima) over many epochs with Embree on
all cores; "cpu" is the process CPU time per epoch with one Embree thread, which is less
sensitive to other processes competing for the cores (the load average is printed).

Run: ``uv run python experiments/bench_simulation.py [--repeats N]``.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from planodom.simulation import (
    SensorRig,
    Simulator,
    WaypointTrajectory,
    isoclinal_rig,
    lidar_rig,
    random_walls,
)

ROUTE = np.array([[-20.0, -20.0], [20.0, -20.0], [20.0, 20.0], [-20.0, 20.0]])


def _laps(fn, repeats: int) -> tuple[np.ndarray, float]:
    """Wall seconds of each of ``repeats`` calls of ``fn(i)`` and the mean CPU seconds."""
    fn(0)
    laps = np.empty(repeats)
    cpu0 = time.process_time()
    for i in range(repeats):
        t0 = time.perf_counter()
        fn(i)
        laps[i] = time.perf_counter() - t0
    return laps, (time.process_time() - cpu0) / repeats


def bench(name: str, rig: SensorRig, target_ms: float, repeats: int) -> None:
    sim = Simulator(
        random_walls(100, extent=60.0, seed=1), WaypointTrajectory(ROUTE), rig.with_noise(0.006)
    )
    rays = [sim.rays(0.1 * k) for k in range(repeats)]
    n_rays = float(np.mean([len(r) for r in rays]))
    epoch, _ = _laps(lambda i: sim.epoch(i, 0.1 * i), repeats)
    cast, _ = _laps(lambda i: sim.caster.cast_rays(rays[i], 80.0), repeats)
    sim.caster.nthreads = 1
    _, cpu = _laps(lambda i: sim.epoch(i, 0.1 * i), repeats)
    ms = np.median(epoch) * 1e3
    print(
        f"{name:<24} {n_rays:7.0f} rays | epoch {ms:5.2f} ms (min {epoch.min() * 1e3:5.2f}, "
        f"cpu 1 thread {cpu * 1e3:5.2f}) {n_rays / np.median(epoch) / 1e6:5.2f} Mrays/s | "
        f"cast {np.median(cast) * 1e3:5.2f} ms (min {cast.min() * 1e3:5.2f}) "
        f"{n_rays / np.median(cast) / 1e6:5.2f} Mrays/s | target < {target_ms:g} ms: "
        f"{'ok' if ms < target_ms else 'MISSED'}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=200)
    args = parser.parse_args()
    load = os.getloadavg()[0]
    print(
        f"random_walls(100): 101 polygons; {args.repeats} epochs each; "
        f"{os.cpu_count()} cores, load average {load:.2f}"
    )
    bench("(a) isoclinal 4x361x7.5", isoclinal_rig(), 2.0, args.repeats)
    bench("(b) lidar 32x1024", lidar_rig(32, n_columns=1024), 5.0, args.repeats)


if __name__ == "__main__":
    main()
