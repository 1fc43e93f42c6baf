"""Where the 2D rig's epoch spends its CPU time outside compiled code: cProfile by process
time, ranked by owner.

Per world and noise: the run simulated once, the default odometry run once untimed
(numba's kernels loaded, caches warm), once plain (process time, ms an epoch) and once
under cProfile with ``time.process_time`` as its timer. The profile's own times are then
summed by owner: numba's compiled kernels (each kernel's call, boxing included), each
planodom module's Python lines (numpy's operators, indexing and attribute access inside
them count there: cProfile does not see them), numpy's Python-level functions, the C
functions called (numpy's ``array``, ufunc reductions, ``len``), numba's unpickling of
the types of the arrays a kernel returns, and open3d, gtsam and scipy (the front end
calls none of them on the 2D rig). cProfile costs about a microsecond a Python call, so
the Python shares are inflated against the kernels': the kernels' own time over the plain
run's CPU is the better estimate of the compiled share. ``--out`` keeps the raw profiles
(``pstats``).

    uv run python experiments/profile_rig2d_shares.py --worlds 162 168 --noise 0.02 0.006
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import cProfile  # noqa: E402
import importlib  # noqa: E402
import pstats  # noqa: E402
import time  # noqa: E402
from collections import defaultdict  # noqa: E402
from pathlib import Path  # noqa: E402

import numba  # noqa: E402

from planodom.config import PlanodomConfig  # noqa: E402
from planodom.experiments.generalisation import declared_sweep, world_for  # noqa: E402
from planodom.odometry import run_odometry  # noqa: E402
from planodom.simulation.random_world import simulate_world, world_fields  # noqa: E402


def _kernel(path: str, name: str) -> bool:
    """Whether ``name`` of the planodom module at ``path`` is a numba dispatcher."""
    if "/planodom/" not in path or not path.endswith(".py"):
        return False
    mod = "planodom." + path.rsplit("/planodom/", 1)[1][:-3].replace("/", ".")
    try:
        obj = getattr(importlib.import_module(mod), name, None)
    except ImportError:
        return False
    return isinstance(obj, numba.core.registry.CPUDispatcher)


def owner(path: str, name: str) -> str:
    """The owner a profile entry's own time is summed under (module docstring)."""
    if _kernel(path, name):
        return "compiled kernels"
    if "/planodom/" in path:
        return path.rsplit("/planodom/", 1)[1]
    for lib in ("open3d", "gtsam", "scipy"):
        if f"/{lib}/" in path:
            return lib
    if "/numba/" in path:
        return f"numba: {name}"
    if "/numpy/" in path:
        return "numpy (Python-level functions)"
    if path == "~":
        return "C calls: " + name.strip("<>").replace("built-in method ", "")[:40]
    return "other Python: " + Path(path).name


def shares(stats: pstats.Stats) -> dict[str, float]:
    """Own CPU seconds by owner."""
    out: dict[str, float] = defaultdict(float)
    for (path, _, name), row in stats.stats.items():  # type: ignore[attr-defined]
        out[owner(path, name)] += row[2]
    return out


def one(w: int, noise: float, epochs: int, top: int, out: Path | None) -> None:
    """Profile world ``w`` at ``noise`` and print its shares."""
    world = world_for(w)
    cfg = declared_sweep(world, PlanodomConfig())
    run = world_fields(world, simulate_world(world, noise, n_epochs=epochs, all_fields=True))
    run_odometry(run, cfg)
    c0 = time.process_time()
    run_odometry(run, cfg)
    plain = time.process_time() - c0
    prof = cProfile.Profile(time.process_time)
    prof.enable()
    run_odometry(run, cfg)
    prof.disable()
    stats = pstats.Stats(prof)
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        stats.dump_stats(out / f"w{w}_{noise * 1e3:g}mm.prof")
    by = shares(stats)
    total = sum(by.values())
    kern = by.get("compiled kernels", 0.0)
    print(f"world {w} ({world.kind}) {noise * 1e3:g} mm: plain {1e3 * plain / epochs:.2f} ms an "
          f"epoch; profiled {1e3 * total / epochs:.2f}; kernels {1e3 * kern / epochs:.2f} ms "
          f"= {100 * kern / total:.1f} % of the profile, {100 * kern / plain:.1f} % of the "
          "plain run", flush=True)  # fmt: skip
    for k, v in sorted(by.items(), key=lambda kv: -kv[1])[:top]:
        print(f"  {100 * v / total:5.1f} %  {1e6 * v / epochs:7.1f} us an epoch  {k}")
    for lib in ("open3d", "gtsam", "scipy"):
        if lib not in by:
            print(f"  {lib}: not called")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--worlds", type=int, nargs="+", default=[162, 168])
    ap.add_argument("--noise", type=float, nargs="+", default=[0.02, 0.006])
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--top", type=int, default=25)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args()
    for noise in args.noise:
        for w in args.worlds:
            one(w, noise, args.epochs, args.top, args.out)


if __name__ == "__main__":
    main()
