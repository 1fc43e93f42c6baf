"""SPEED2D11's SDA and refinement in compiled calls (:mod:`planodom.sda_kernel`,
:mod:`planodom.odometry.refine_loop`, scipy's assignment ported: :mod:`planodom.lsap`)
against the calls they replace (SDA's costs kernel, scipy's ``linear_sum_assignment``, the
gate kernel; the refinement's SDA and fits with Python between them), in one process,
with KISS-ICP on the same scans.

The 2D rig's default odometry runs each world's simulated run as it is ("cuts") and as
it was ("former": ``association.sda_kernel`` answered by
``association.scipy_strict_pairs``, ``refine_loop.compiled_refine`` by None),
alternating, ``--reps`` times each after an untimed warm-up of both, and KISS-ICP on the
same scans (``bench_glue_cuts.py``'s loop: the fastest repetition of each counts,
process time; the two variants' poses must be the same bits, checked on every
repetition). ``--calls`` instead captures the solver's refinements and its own SDA calls
in one run of each world and replays them (10 times a round, best of 5 rounds, process
time) both ways: microseconds a call and saved an epoch, less moved by the load.

    uv run --extra baselines python experiments/bench_sda_kernel.py --noise 0.02 \\
        --epochs 150 --worlds 160 162 164 168 170 172 --reps 5
    uv run python experiments/bench_sda_kernel.py --calls --noise 0.02 --worlds 162 168
"""

from __future__ import annotations

import sys
import time
from typing import Any

import bench_glue_cuts

import planodom.association as association
import planodom.odometry.solver as solver
from planodom.lsap import SOLVED
from planodom.odometry import refine_loop


def former_sda(*args: Any) -> tuple[int, Any]:
    """SDA before SPEED2D11: the costs, scipy's assignment and the gate, three calls."""
    return SOLVED, association.scipy_strict_pairs(*args)


def former_refine(*args: Any) -> None:
    """The refinement before SPEED2D11: its calls (``refine_loop.called_refine``)."""
    return None


#: (object, attribute, former): what "former" puts back
FORMER = (
    (association, "sda_kernel", former_sda),
    (refine_loop, "compiled_refine", former_refine),
)
CUTS = bench_glue_cuts.cuts_of(FORMER)


def _best(calls: list[tuple[Any, tuple]], variant: str) -> float:
    """Seconds of one replay of ``calls`` (function, args), best of 5 rounds of 10."""
    bench_glue_cuts.use(variant, CUTS, FORMER)
    rounds = []
    for _ in range(5):
        c0 = time.process_time()
        for _ in range(10):
            for fn, args in calls:
                fn(*args)
        rounds.append((time.process_time() - c0) / 10)
    bench_glue_cuts.use("cuts", CUTS, FORMER)
    return min(rounds)


def calls(worlds: list[int], noise: float, epochs: int) -> None:
    """Print, per world, the captured calls' CPU a call with either variant: the
    solver's refinements (``solver.refine``) and its own SDA calls (the final one)."""
    from planodom.config import PlanodomConfig
    from planodom.experiments.generalisation import declared_sweep, world_for
    from planodom.odometry import run_odometry
    from planodom.simulation.random_world import simulate_world, world_fields

    for w in worlds:
        seen: dict[str, list[tuple[Any, tuple]]] = {"refine": [], "sda": []}
        originals = {"refine": solver.refine, "sda": solver.strict_association}

        def spy(name: str, seen: dict = seen, originals: dict = originals) -> Any:
            def wrapper(*args: Any) -> Any:
                seen[name].append((originals[name], args))
                return originals[name](*args)

            return wrapper

        world = world_for(w)
        run = world_fields(world, simulate_world(world, noise, n_epochs=epochs, all_fields=True))
        cfg = declared_sweep(world, PlanodomConfig())
        run_odometry(run, cfg)  # untimed: caches warm
        setattr(solver, "refine", spy("refine"))  # noqa: B010
        setattr(solver, "strict_association", spy("sda"))  # noqa: B010
        run_odometry(run, cfg)
        setattr(solver, "refine", originals["refine"])  # noqa: B010
        setattr(solver, "strict_association", originals["sda"])  # noqa: B010
        for name, got in seen.items():
            best = {v: _best(got, v) for v in ("former", "cuts")}
            per = {k: 1e6 * v / max(len(got), 1) for k, v in best.items()}
            saved = 1e6 * (best["former"] - best["cuts"]) / epochs
            print(f"world {w} {name}: {len(got)} calls ({len(got) / epochs:.2f} an epoch), us a "
                  f"call former {per['former']:.1f} cuts {per['cuts']:.1f}, saved {saved:.1f} us "
                  "an epoch", flush=True)  # fmt: skip


if __name__ == "__main__":
    if "--calls" in sys.argv:
        sys.argv.remove("--calls")
        import argparse

        ap = argparse.ArgumentParser()
        ap.add_argument("--worlds", type=int, nargs="+", default=[160, 162])
        ap.add_argument("--noise", type=float, default=0.02)
        ap.add_argument("--epochs", type=int, default=150)
        a = ap.parse_args()
        calls(a.worlds, a.noise, a.epochs)
        sys.exit(0)
    bench_glue_cuts.main(CUTS, FORMER, __doc__)
