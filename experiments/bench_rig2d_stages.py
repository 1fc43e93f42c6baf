"""Where the 2D rig's streaming odometry spends its CPU time, stage by stage.

Simulates 2D-rig worlds of ``planodom experiment generalisation`` (even indices), runs the
default odometry once to warm up, then once more with CPU-time accumulators around its
stages (the functions as their callers import them): per stage the calls per epoch, the
microseconds per call and the share of the run. Stages nest (the extraction holds the
split, the grouping, the refits and the plane builder; the relative pose holds the
solves), so the shares do not add up. The accumulators cost about a microsecond a call:
compare stages with each other, and whole runs only without them (``--plain``).

    uv run python experiments/bench_rig2d_stages.py --worlds 44 60 78 --noise 0.02
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import importlib  # noqa: E402
import time  # noqa: E402
from collections import defaultdict  # noqa: E402
from collections.abc import Callable  # noqa: E402
from typing import Any  # noqa: E402

from planodom.config import PlanodomConfig  # noqa: E402
from planodom.experiments.generalisation import declared_sweep, world_for  # noqa: E402
from planodom.odometry import run_odometry  # noqa: E402
from planodom.simulation.random_world import simulate_world, world_fields  # noqa: E402

#: (module, name as that module holds it, label): the stages, outermost first.
STAGES = (
    ("planodom.odometry.odometry", "widened_if_lost", "one extraction + estimate (and retry)"),
    ("planodom.extraction.pipeline", "rig2d_planes", "extraction: 2D-rig path"),
    ("planodom.extraction.pipeline", "_deskewed", "extraction: deskewing"),
    ("planodom.extraction.pipeline", "_check_inputs", "extraction: input checks"),
    ("planodom.extraction.rig2d.path", "split_scan_lines", "  scan lines to segments"),
    ("planodom.extraction.rig2d.path", "group_segments", "  traces and grouping"),
    ("planodom.extraction.rig2d.path", "_group_fits", "  group refits"),
    ("planodom.extraction.rig2d.path", "build_planes", "  plane builder"),
    ("planodom.odometry.odometry", "estimate_relative_pose", "relative pose (solver)"),
    ("planodom.odometry.solver", "_solve", "  one solve"),
    ("planodom.odometry.solver", "lenient_association", "    LDA association"),
    ("planodom.odometry.solver", "_rotation", "    rotation consensus + covariance"),
    ("planodom.odometry.solver", "_measured_translation", "    translation consensus"),
    ("planodom.odometry.solver", "_refine", "    refinement"),
    ("planodom.odometry.solver", "strict_association", "    SDA association"),
    ("planodom.odometry.odometry", "predicted_twist", "twist prediction"),
    ("planodom.odometry.odometry", "is_gap", "gap test"),
)


def _timed(
    fn: Callable[..., Any], key: str, acc: defaultdict[str, float], n: defaultdict[str, int]
) -> Any:
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        c0 = time.process_time()
        try:
            return fn(*args, **kwargs)
        finally:
            acc[key] += time.process_time() - c0
            n[key] += 1

    return wrapper


def instrument(
    acc: defaultdict[str, float],
    n: defaultdict[str, int],
    stages: tuple[tuple[str, str, str], ...] = STAGES,
) -> list[str]:
    """Wrap the ``stages`` (module or module.Class, name, label) that exist; their labels,
    in order (``bench_lidar_stages.py`` times its own stages with it)."""
    labels = []
    for module, name, label in stages:
        try:
            mod: Any = importlib.import_module(module)
        except ModuleNotFoundError:  # a class of the module before it
            parent, cls = module.rsplit(".", 1)
            mod = getattr(importlib.import_module(parent), cls)
        if not hasattr(mod, name):
            continue
        setattr(mod, name, _timed(getattr(mod, name), label, acc, n))
        labels.append(label)
    return labels


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--worlds", type=int, nargs="+", default=[44, 60, 78])
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--plain", action="store_true", help="whole runs only, no accumulators")
    args = ap.parse_args()
    acc: defaultdict[str, float] = defaultdict(float)
    n: defaultdict[str, int] = defaultdict(int)
    labels = [] if args.plain else instrument(acc, n)
    for w in args.worlds:
        if w % 2:
            raise SystemExit(f"world {w} is a lidar world; the 2D rig's are even")
        world = world_for(w)
        cfg = declared_sweep(world, PlanodomConfig())
        sim = simulate_world(world, args.noise, n_epochs=args.epochs, all_fields=True)
        run = world_fields(world, sim)
        warm = simulate_world(world, 0.0, n_epochs=3, all_fields=True)
        run_odometry(world_fields(world, warm), cfg)
        acc.clear()
        n.clear()
        c0 = time.process_time()
        run_odometry(run, cfg)
        total = time.process_time() - c0
        ms = 1e3 * total / args.epochs
        print(f"world {w}, {args.noise * 1e3:g} mm: {ms:.2f} ms CPU an epoch")
        for label in labels:
            if n[label]:
                per = 1e6 * acc[label] / n[label]
                share = 100 * acc[label] / total
                calls = n[label] / args.epochs
                print(f"  {label:38s} {calls:5.2f}/epoch {per:7.0f} us {share:5.1f} %")


if __name__ == "__main__":
    main()
