"""How much of the 2D rig's CPU time is compiled kernels and how much the glue around them.

Simulates 2D-rig worlds of ``planodom experiment generalisation`` (even indices), runs the
default odometry on a few noise-free epochs and then once on the run (untimed: every
kernel specialisation the run reaches is then loaded, see ``kernel_signatures.py``), then
once more plain (the CPU time an epoch), and once with a CPU-time accumulator around every
numba kernel that Python calls (the dispatchers held by planodom's modules; kernels
called from kernels are compiled into them). A kernel's time includes its dispatch and the
boxing of its results. Per world: points an epoch, CPU ms an epoch, extractions (passes)
and solves an epoch, ms a pass, the kernels' ms an epoch and share, their calls an epoch,
and the glue (the rest) per pass; with ``--top`` the kernels taking most. The
accumulator's own cost (timed on an empty function) is left out of the kernels' time.

    uv run python experiments/bench_rig2d_glue.py --worlds 160 162 168 172 --noise 0.02
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import importlib  # noqa: E402
import pkgutil  # noqa: E402
import time  # noqa: E402
from collections import defaultdict  # noqa: E402
from collections.abc import Callable  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

# the stage bench's wrappers count the passes (this script runs beside it in experiments/);
# numba's dispatcher class: what a compiled kernel is
from bench_rig2d_stages import instrument  # noqa: E402
from numba.core.registry import CPUDispatcher  # noqa: E402

import planodom  # noqa: E402
from planodom.config import PlanodomConfig  # noqa: E402
from planodom.experiments.generalisation import declared_sweep, world_for  # noqa: E402
from planodom.odometry import run_odometry  # noqa: E402
from planodom.simulation.random_world import simulate_world, world_fields  # noqa: E402

COUNTED = (
    ("planodom.extraction.pipeline", "rig2d_planes", "extractions"),
    ("planodom.odometry.solver", "_solve", "solves"),
)


def _accumulated(fn: Callable[..., Any], key: str, acc: dict[str, float], n: dict[str, int]):
    """``fn`` with its CPU time added to ``acc[key]`` and its calls to ``n[key]``."""
    clock = time.process_time

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        c0 = clock()
        try:
            return fn(*args, **kwargs)
        finally:
            acc[key] += clock() - c0
            n[key] += 1

    return wrapper


def wrap_kernels(acc: dict[str, float], n: dict[str, int]) -> int:
    """Every numba dispatcher a planodom module holds replaced there by an accumulating
    wrapper; returns how many. Call only after the runs to time have reached every
    specialisation: a kernel compiled later would find a wrapper where its callee was."""
    count = 0
    for info in pkgutil.walk_packages(planodom.__path__, "planodom."):
        try:
            mod = importlib.import_module(info.name)
        except ImportError:  # an optional extra's module
            continue
        for name, obj in list(vars(mod).items()):
            if isinstance(obj, CPUDispatcher):
                setattr(mod, name, _accumulated(obj, name, acc, n))
                count += 1
    return count


def _wrapper_cost(acc: dict[str, float], n: dict[str, int], calls: int = 100_000) -> float:
    """CPU seconds the accumulator itself adds to a call's measured time (an empty
    function timed through it: its time inside, i.e. about one clock read)."""
    nop = _accumulated(lambda: None, "_nop", acc, n)
    for _ in range(calls):
        nop()
    cost = acc.pop("_nop") / calls
    n.pop("_nop")
    return cost


def one_world(w: int, noise: float, epochs: int, n_pass: defaultdict[str, int]) -> dict:
    """Plain run of world ``w`` (module docstring); the run and config for the kernel run."""
    world = world_for(w)
    cfg = declared_sweep(world, PlanodomConfig())
    run = world_fields(world, simulate_world(world, noise, n_epochs=epochs, all_fields=True))
    warm = world_fields(world, simulate_world(world, 0.0, n_epochs=3, all_fields=True))
    run_odometry(warm, cfg)
    run_odometry(run, cfg)  # every specialisation the run reaches, loaded
    n_pass.clear()
    c0 = time.process_time()
    run_odometry(run, cfg)
    total = time.process_time() - c0
    return {
        "world": w, "kind": world.kind, "run": run, "cfg": cfg, "total": total,
        "points": float(np.mean([len(s) for s in run.scans])),
        "extractions": n_pass["extractions"] / epochs, "solves": n_pass["solves"] / epochs,
    }  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--worlds", type=int, nargs="+", default=[160, 162, 168, 172])
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--epochs", type=int, default=80)
    ap.add_argument("--top", type=int, default=0, help="list the N kernels taking most")
    args = ap.parse_args()
    if any(w % 2 for w in args.worlds):
        raise SystemExit("the 2D rig's worlds are the even ones")
    n_pass: defaultdict[str, int] = defaultdict(int)
    instrument(defaultdict(float), n_pass, COUNTED)
    plain = [one_world(w, args.noise, args.epochs, n_pass) for w in args.worlds]
    acc: defaultdict[str, float] = defaultdict(float)
    n: defaultdict[str, int] = defaultdict(int)
    wrap_kernels(acc, n)
    cost = _wrapper_cost(acc, n)
    e = args.epochs
    print(f"{args.noise * 1e3:g} mm, {e} epochs, CPU; accumulator {cost * 1e6:.2f} us a call")
    for r in plain:
        acc.clear()
        n.clear()
        run_odometry(r["run"], r["cfg"])
        calls = sum(n.values())
        kernels = max(sum(acc.values()) - calls * cost, 0.0)
        ms, passes = 1e3 * r["total"] / e, r["extractions"]
        glue_ms = 1e3 * (r["total"] - kernels) / e
        print(
            f"world {r['world']:3d} {r['kind']:7s} {r['points']:6.0f} points | {ms:5.2f} ms "
            f"an epoch, {passes:.2f} passes, {r['solves']:.2f} solves, {ms / passes:.2f} ms a "
            f"pass | kernels {1e3 * kernels / e:.2f} ms ({100 * kernels / r['total']:.0f} %, "
            f"{calls / e:.0f} calls) | glue {glue_ms / passes:.2f} ms a pass",
            flush=True,
        )
        for key, t in sorted(acc.items(), key=lambda kv: -kv[1])[: args.top]:
            print(f"    {key:28s} {n[key] / e:5.1f} an epoch {1e6 * t / n[key]:7.1f} us a call")


if __name__ == "__main__":
    main()
