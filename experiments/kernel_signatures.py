"""Which compiled kernels get a new numba specialisation in which run of a world sweep.

numba compiles one specialisation per argument type (a read-only or strided array is a
type of its own); the first run to reach one pays its compile, seconds of CPU on a cold
cache, inside its timed section. Runs ``planodom experiment generalisation``'s warm-up on
the first two worlds, then every world at 6 mm and 2 cm (planodom only), and after each run
prints the specialisations that the planodom kernels gained during it.

    uv run python experiments/kernel_signatures.py --worlds 160 162 164 166
"""

from __future__ import annotations

import argparse
import sys
import time

from numba.core.registry import CPUDispatcher

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import _warm_up, run_world, world_for


def signatures() -> dict[str, set[str]]:
    """Every planodom kernel loaded so far: its name and its specialisations."""
    out: dict[str, set[str]] = {}
    for name, module in list(sys.modules.items()):
        if not name.startswith("planodom"):
            continue
        for value in list(vars(module).values()):
            if isinstance(value, CPUDispatcher):
                key = f"{value.py_func.__module__}.{value.py_func.__name__}"
                out[key] = {str(s) for s in value.signatures}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--worlds", type=int, nargs="+", default=[160, 162, 164])
    ap.add_argument("--noise", type=float, nargs="+", default=[0.006, 0.02])
    ap.add_argument("--epochs", type=int, default=150)
    args = ap.parse_args()
    base = PlanodomConfig()
    for w in args.worlds[:2]:
        _warm_up(world_for(w), base, ["planodom"])
    before = signatures()
    for w in args.worlds:
        for noise in args.noise:
            c0 = time.process_time()
            run_world(world_for(w), noise, args.epochs, base, ["planodom"], lambda msg: None)
            now = signatures()
            print(f"world {w}, {noise * 1e3:g} mm: {time.process_time() - c0:.1f} s CPU")
            for key, sigs in now.items():
                for sig in sorted(sigs - before.get(key, set())):
                    print(f"  new: {key} {sig[:200]}")
            before = now


if __name__ == "__main__":
    main()
