"""Where a simulated lidar world's streaming odometry spends its CPU time, and KISS-ICP's.

For each world (``planodom experiment generalisation``'s seeds; ``--family`` swaps the
lidar of the same scene and route: ``random_world(seed, rig=family)`` draws everything
else from the same stream) simulates ``--epochs`` epochs at ``--noise``, warms both
methods up, then times, as CPU time (``time.process_time``): planodom's ``run_odometry``
with accumulators around its stages, and KISS-ICP on the same scans (one thread, as the
experiment runs it). Prints per world the points an epoch, the extractions an epoch, the
CPU time an epoch of both and their ratio, and per stage the calls an epoch, the
microseconds a call and the share of planodom's run. Stages nest; the shares do not add
up. Needs ``uv sync --extra baselines``.

    uv run python experiments/bench_lidar_stages.py --worlds 13 3 --family lidar16 lidar32
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402
from collections import defaultdict  # noqa: E402

import numpy as np  # noqa: E402

# the stage timers (this script runs beside it in experiments/)
from bench_rig2d_stages import instrument  # noqa: E402

from planodom.config import PlanodomConfig  # noqa: E402
from planodom.experiments.generalisation import declared_sweep, world_for  # noqa: E402
from planodom.experiments.peers import kiss_icp_poses  # noqa: E402
from planodom.odometry import run_odometry  # noqa: E402
from planodom.simulation.random_world import random_world, simulate_world, world_fields  # noqa: E402

#: (module, name as that module holds it, label): the stages, outermost first.
STAGES = (
    ("planodom.odometry.run", "_streaming_pass", "streaming pass"),
    ("planodom.odometry.run", "_middle_timed_pass", "mid-time pass"),
    ("planodom.extraction.pipeline", "lidar_planes", "extraction: lidar path"),
    ("planodom.extraction.pipeline", "deskew_points", "extraction: deskewing"),
    ("planodom.extraction.lidar.path", "_scan_rows", "  rows recovered"),
    ("planodom.extraction.lidar.path", "_organised_planes", "  square-pixel image path"),
    ("planodom.extraction.lidar.path", "lidar_candidates", "  candidates"),
    ("planodom.extraction.lidar.candidates", "ring_noise", "    ring noise"),
    ("planodom.extraction.lidar.candidates", "range_image_candidates", "    range image"),
    ("planodom.extraction.lidar.rangeimage", "grid_indices", "      grid indices"),
    ("planodom.extraction.lidar.rangeimage", "point_grid", "      point grid"),
    ("planodom.extraction.lidar.rangeimage", "pixel_normals", "      pixel normals"),
    ("planodom.extraction.lidar.rangeimage", "row_spacing", "      row spacing"),
    ("planodom.extraction.lidar.rangeimage", "_grow_pieces", "      growing"),
    ("planodom.extraction.lidar.rangeimage", "_flat_pieces", "      flat pieces"),
    ("planodom.extraction.lidar.rangeimage", "_merge_pieces", "      merging"),
    ("planodom.extraction.lidar.rangeimage", "assign_points", "      point assignment"),
    ("planodom.extraction.lidar.rangeimage", "plane_members", "      members"),
    ("planodom.extraction.lidar.candidates", "ransac_candidates", "    RANSAC fallback"),
    ("planodom.extraction.lidar.path", "fit_candidates", "  robust fits"),
    ("planodom.extraction.lidar.path", "build_planes", "  plane builder"),
    ("planodom.odometry.odometry", "widened_if_lost", "extraction + estimate (and retry)"),
    ("planodom.odometry.planemap.odometry.PlaneMapOdometry", "estimate", "map estimate"),
    ("planodom.odometry.planemap.odometry", "register", "  map registration"),
    ("planodom.odometry.planemap.odometry", "register_twist", "  twist registration"),
    ("planodom.odometry.planemap.odometry", "relative_pose", "  relative pose, covariance"),
    ("planodom.odometry.planemap.odometry.PlaneMapOdometry", "commit", "map commit"),
    ("planodom.odometry.planemap.odometry", "update_map", "map update"),
    ("planodom.odometry.planemap.fallback", "lda_hypothesis", "LDA fallback"),
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--worlds", type=int, nargs="+", default=[13, 3])
    ap.add_argument("--family", nargs="*", default=[], help="lidar16 | lidar32 | lidar64")
    ap.add_argument("--noise", type=float, default=0.006)
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--plain", action="store_true", help="whole runs only, no accumulators")
    args = ap.parse_args()
    acc: defaultdict[str, float] = defaultdict(float)
    n: defaultdict[str, int] = defaultdict(int)
    labels = [] if args.plain else instrument(acc, n, STAGES)
    for w in args.worlds:
        for fam in args.family or [None]:
            world = random_world(w, rig=fam) if fam else world_for(w)
            cfg = declared_sweep(world, PlanodomConfig())
            sim = simulate_world(world, args.noise, n_epochs=args.epochs, all_fields=True)
            run = world_fields(world, sim)
            warm = world_fields(world, simulate_world(world, 0.0, n_epochs=3, all_fields=True))
            max_range = max(s.max_range for s in world.sensor_rig.sensors)
            run_odometry(warm, cfg)
            kiss_icp_poses(warm.scans, 1.0 / world.epoch_rate, max_range)
            acc.clear()
            n.clear()
            c0 = time.process_time()
            odo = run_odometry(run, cfg)
            total = time.process_time() - c0
            c0 = time.process_time()
            kiss_icp_poses(run.scans, 1.0 / world.epoch_rate, max_range)
            kiss = time.process_time() - c0
            E = args.epochs
            pts = np.mean([len(s) for s in run.scans])
            d = world.description
            print(f"world {w} {d['kind']} {d['family']} {d['columns']} col, ring {d['ring']},"
                  f" time {d['time']}, {args.noise * 1e3:g} mm: {pts:.0f} points, planodom "
                  f"{1e3 * total / E:.2f} ms, KISS-ICP {1e3 * kiss / E:.2f} ms an epoch, "
                  f"ratio of speeds {kiss / total:.3f}, {np.mean(odo.n_planes):.1f} planes, "
                  f"unresolved {odo.n_unresolved}")  # fmt: skip
            for label in labels:
                if n[label]:
                    per = 1e6 * acc[label] / n[label]
                    share = 100 * acc[label] / total
                    print(f"  {label:32s} {n[label] / E:5.2f}/epoch {per:8.0f} us {share:5.1f} %")


if __name__ == "__main__":
    main()
