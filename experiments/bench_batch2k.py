"""The 2 000-epoch lap's batch with loops, timed on cached inputs (BATCH15, issue 14).

``run_loop_experiment(None, [0], (0.006,), 2000)`` spends most of its hour in the odometry;
the issue's 60 s figure is the batch with loops alone. ``cache`` runs the lap's odometry once
(world 0 at 6 mm, 2 000 epochs, the smoothing's odometry config as ``run_loop_world``) and
pickles what :func:`smooth_batch` reads: the epochs' planes, the smoothing relatives, the
ground truth (origin-aligned) and the odometry's poses. ``time`` re-times
``smooth_batch(planes, relatives, config)`` with ``smoothing.loop_closure`` on, as
``compare_methods`` runs it, ``--repeats`` times, and prints wall and process time, the
machine's load and the ATE; ``--save FILE`` keeps the last run's poses and covariances
(``.npz``) so two checkouts' outputs can be compared bit for bit; ``--set JSON`` overrides
config fields (e.g. ``{"smoothing.batch_initial_concurrent": true}``, whose child process's
CPU time is printed as "children").

    uv run python experiments/bench_batch2k.py cache FILE.pkl [--epochs 2000]
    uv run python experiments/bench_batch2k.py time FILE.pkl [--repeats 3] [--save FILE.npz] \\
        [--set JSON]
"""

from __future__ import annotations

import argparse
import json
import os
import pickle
import resource
import time
from pathlib import Path

import numpy as np

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import world_for
from planodom.geometry import invert_transform
from planodom.metrics import ate
from planodom.odometry import run_odometry
from planodom.simulation.random_world import simulate_world, world_fields
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.run import smoothing_config, smoothing_relatives


def cache(path: Path, world: int, noise: float, epochs: int) -> None:
    """Run the lap's odometry once and pickle the batch's inputs to ``path``."""
    config = PlanodomConfig()
    w = world_for(world)
    full = simulate_world(w, noise, n_epochs=epochs, all_fields=True)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    start = time.process_time()
    odo = run_odometry(world_fields(w, full), smoothing_config(config))
    relatives = smoothing_relatives(odo, config)
    print(f"odometry {time.process_time() - start:.1f} s CPU, {len(odo.planes)} epochs")
    data = {"planes": odo.planes, "relatives": relatives, "gt": gt, "odometry_poses": odo.poses,
            "world": world, "noise": noise, "epochs": epochs}  # fmt: skip
    path.write_bytes(pickle.dumps(data))


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def time_batch(path: Path, repeats: int, save: Path | None, changes: dict) -> None:
    """Time the batch with loops on the cached inputs ``repeats`` times."""
    data = pickle.loads(path.read_bytes())
    cfg = PlanodomConfig().updated({"smoothing.loop_closure": True, **changes})
    for k in range(repeats):
        load = os.getloadavg()[0]
        wall, cpu, child = time.perf_counter(), time.process_time(), _children_cpu()
        res = smooth_batch(data["planes"], data["relatives"], cfg)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        child = _children_cpu() - child
        a = ate(res.poses, data["gt"], xy_only=True)["rmse"]
        print(f"run {k}: wall {wall:.1f} s, CPU {cpu:.1f} s (+ children {child:.1f} s), load "
              f"{load:.2f} -> {os.getloadavg()[0]:.2f}, ATE {a:.7f} m", flush=True)  # fmt: skip
    if save is not None:
        cov = res.covariances if res.covariances is not None else np.zeros(0)
        np.savez(save, poses=res.poses, covariances=cov)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    c = sub.add_parser("cache")
    c.add_argument("path", type=Path)
    c.add_argument("--world", type=int, default=0)
    c.add_argument("--noise", type=float, default=0.006)
    c.add_argument("--epochs", type=int, default=2000)
    t = sub.add_parser("time")
    t.add_argument("path", type=Path)
    t.add_argument("--repeats", type=int, default=3)
    t.add_argument("--save", type=Path)
    t.add_argument("--set", default="{}", help="config changes, JSON")
    args = parser.parse_args()
    if args.command == "cache":
        cache(args.path, args.world, args.noise, args.epochs)
    else:
        time_batch(args.path, args.repeats, args.save, json.loads(args.set))


if __name__ == "__main__":
    main()
