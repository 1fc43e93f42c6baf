"""SPEED2D10's measured translation in two compiled calls against the numpy path it
replaces, in one process, with KISS-ICP on the same scans.

The 2D rig's default odometry runs each world's simulated run with the solver's
translation as it is ("cuts": :mod:`planodom.odometry.fused_translation`) and with the
numpy path ("former": ``fused_translation`` answering None, so the solver's
``_elements_translation`` runs), alternating, ``--reps`` times each after an untimed
warm-up of both, and KISS-ICP on the same scans (``bench_glue_cuts.py``'s loop: the
fastest repetition of each counts, process time; the two variants' poses must be the
same bits, checked on every repetition). ``--count`` first counts, on one run of each
world, the solves the compiled path served and those it handed to numpy. ``--calls``
instead captures the solver's ``_measured_translation`` calls of one run of each world
and replays them (10 times a round, best of 5 rounds, process time) with either
variant: microseconds a call and saved an epoch, less moved by the machine's load.

    uv run --extra baselines python experiments/bench_fused_translation.py --noise 0.02 \\
        --epochs 150 --worlds 160 162 164 168 170 172 --reps 5
"""

from __future__ import annotations

import sys
from typing import Any

import bench_glue_cuts

import planodom.odometry.solver as solver


def former_fused_translation(*args: Any) -> None:
    """The solver's translation before SPEED2D10: the numpy path always."""
    return None


#: (object, attribute, former): what "former" puts back
FORMER = ((solver, "fused_translation", former_fused_translation),)
CUTS = bench_glue_cuts.cuts_of(FORMER)


def _put(name: str, fn: Any) -> None:
    """Put ``fn`` in the solver's module as ``name``."""
    setattr(solver, name, fn)


def count(worlds: list[int], noise: float, epochs: int) -> None:
    """Print, per world, the solves the compiled path served and those it left to numpy."""
    from planodom.config import PlanodomConfig
    from planodom.experiments.generalisation import declared_sweep, world_for
    from planodom.odometry import run_odometry
    from planodom.simulation.random_world import simulate_world, world_fields

    fused = CUTS[0][2]
    for w in worlds:
        n = {"compiled": 0, "numpy": 0}

        def counted(*args: Any, n: dict = n) -> Any:
            out = fused(*args)
            n["numpy" if out is None else "compiled"] += 1
            return out

        _put("fused_translation", counted)
        world = world_for(w)
        run = world_fields(world, simulate_world(world, noise, n_epochs=epochs, all_fields=True))
        run_odometry(run, declared_sweep(world, PlanodomConfig()))
        print(f"world {w}: {n['compiled']} solves compiled, {n['numpy']} to numpy", flush=True)
    _put("fused_translation", fused)


def calls(worlds: list[int], noise: float, epochs: int) -> None:
    """Print, per world, the captured calls' CPU a call with either variant."""
    import time

    from planodom.config import PlanodomConfig
    from planodom.experiments.generalisation import declared_sweep, world_for
    from planodom.odometry import run_odometry
    from planodom.simulation.random_world import simulate_world, world_fields

    measured, fused = solver._measured_translation, CUTS[0][2]
    for w in worlds:
        seen: list[tuple] = []

        def spy(*args: Any, seen: list = seen) -> Any:
            seen.append(args)
            return measured(*args)

        world = world_for(w)
        run = world_fields(world, simulate_world(world, noise, n_epochs=epochs, all_fields=True))
        _put("_measured_translation", spy)
        run_odometry(run, declared_sweep(world, PlanodomConfig()))
        _put("_measured_translation", measured)
        best = {}
        for name, fn in (("former", former_fused_translation), ("cuts", fused)):
            _put("fused_translation", fn)
            rounds = []
            for _ in range(5):
                c0 = time.process_time()
                for _ in range(10):
                    for args in seen:
                        measured(*args)
                rounds.append((time.process_time() - c0) / 10)
            best[name] = min(rounds)
        _put("fused_translation", fused)
        per = {k: 1e6 * v / len(seen) for k, v in best.items()}
        saved = 1e6 * (best["former"] - best["cuts"]) / epochs
        print(f"world {w}: {len(seen)} calls ({len(seen) / epochs:.2f} an epoch), us a call "
              f"former {per['former']:.1f} cuts {per['cuts']:.1f}, saved {saved:.1f} us an epoch",
              flush=True)  # fmt: skip


if __name__ == "__main__":
    if "--calls" in sys.argv or "--count" in sys.argv:
        mode = "calls" if "--calls" in sys.argv else "count"
        sys.argv.remove(f"--{mode}")
        import argparse

        ap = argparse.ArgumentParser()
        ap.add_argument("--worlds", type=int, nargs="+", default=[160, 162])
        ap.add_argument("--noise", type=float, default=0.02)
        ap.add_argument("--epochs", type=int, default=150)
        ap.add_argument("--reps", type=int, default=5)
        a = ap.parse_args()
        (calls if mode == "calls" else count)(a.worlds, a.noise, a.epochs)
        sys.exit(0)
    bench_glue_cuts.main(CUTS, FORMER, __doc__)
