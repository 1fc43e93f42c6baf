"""Benchmark the simulator: rays per second and milliseconds per epoch.

(a) the isoclinal 2D rig (4 scanners x 361 beams x 7 sweeps = 10108 rays) against
    ~100 polygons (``random_walls(100)``), target < 2 ms per epoch;
(b) one 32 x 1024 lidar sweep (32768 rays), target < 5 ms per epoch.

Each is timed for the whole epoch (poses of every firing, ray casting, float64
refinement, noise, points) and for the Embree call alone. Run:
``uv run python experiments/bench_simulation.py [--repeats N]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from planodom.simulation import (
    Simulator,
    WaypointTrajectory,
    isoclinal_rig,
    lidar_rig,
    random_walls,
)


def _time(fn, repeats: int) -> float:
    """Median seconds of ``fn()`` over ``repeats`` calls (after one warm-up call)."""
    fn()
    laps = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        laps.append(time.perf_counter() - t0)
    return float(np.median(laps))


def bench(name: str, rig, target_ms: float, repeats: int) -> None:
    scene = random_walls(100, extent=60.0, seed=1)
    route = np.array([[-20.0, -20.0], [20.0, -20.0], [20.0, 20.0], [-20.0, 20.0]])
    sim = Simulator(scene, WaypointTrajectory(route), rig.with_noise(0.006))
    counter = iter(range(10**9))

    def one_epoch() -> None:
        k = next(counter)
        sim.epoch(k, k / sim.epoch_rate)

    n_rays = np.mean([sum(r.size for r in sim.epoch(k, 0.1 * k).ranges) for k in range(20)])
    n_rays = int(round(n_rays))
    t_epoch = _time(one_epoch, repeats)
    rng = np.random.default_rng(0)
    origins = rng.uniform(-20, 20, (n_rays, 3)) * [1, 1, 0] + [0, 0, 1.8]
    dirs = rng.normal(size=(n_rays, 3)) * [1, 1, 0.2]
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    t_cast = _time(lambda: sim.caster.cast(origins, dirs, 80.0), repeats)
    verdict = "ok" if t_epoch * 1e3 < target_ms else "MISSED"
    print(
        f"{name:<28} {n_rays:>6} rays  {t_epoch * 1e3:6.2f} ms/epoch "
        f"({n_rays / t_epoch / 1e6:5.2f} Mrays/s)  cast only {t_cast * 1e3:5.2f} ms "
        f"({n_rays / t_cast / 1e6:5.2f} Mrays/s)  target < {target_ms:g} ms: {verdict}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=200)
    args = parser.parse_args()
    print(f"scene: random_walls(100) = 101 polygons; median of {args.repeats} epochs")
    bench("(a) isoclinal 4x361x7 sweeps", isoclinal_rig(), 2.0, args.repeats)
    bench("(b) lidar 32x1024", lidar_rig(32, n_columns=1024), 5.0, args.repeats)


if __name__ == "__main__":
    main()
