"""SPEED2D11's SDA in one compiled call (:mod:`planodom.sda_kernel`, scipy's assignment
ported: :mod:`planodom.lsap`) against the three calls it replaces (the costs kernel,
scipy's ``linear_sum_assignment``, the gate kernel), in one process, with KISS-ICP on the
same scans.

The 2D rig's default odometry runs each world's simulated run with SDA as it is ("cuts")
and with the three calls ("former": ``association.sda_kernel`` answered by
``association.scipy_strict_pairs``), alternating, ``--reps`` times each after an untimed
warm-up of both, and KISS-ICP on the same scans (``bench_glue_cuts.py``'s loop: the
fastest repetition of each counts, process time; the two variants' poses must be the
same bits, checked on every repetition). ``--calls`` instead captures SDA's kernel
arguments in one run of each world and replays them (10 times a round, best of 5 rounds,
process time) both ways: microseconds a call and saved an epoch, less moved by the
machine's load.

    uv run --extra baselines python experiments/bench_sda_kernel.py --noise 0.02 \\
        --epochs 150 --worlds 160 162 164 168 170 172 --reps 5
    uv run python experiments/bench_sda_kernel.py --calls --noise 0.02 --worlds 162 168
"""

from __future__ import annotations

import sys
from typing import Any

import bench_glue_cuts

import planodom.association as association
from planodom.lsap import SOLVED


def former_sda(*args: Any) -> tuple[int, Any]:
    """SDA before SPEED2D11: the costs, scipy's assignment and the gate, three calls."""
    return SOLVED, association.scipy_strict_pairs(*args)


#: (object, attribute, former): what "former" puts back
FORMER = ((association, "sda_kernel", former_sda),)
CUTS = bench_glue_cuts.cuts_of(FORMER)


def calls(worlds: list[int], noise: float, epochs: int) -> None:
    """Print, per world, the captured SDA calls' CPU a call with either variant."""
    import time

    from planodom.config import PlanodomConfig
    from planodom.experiments.generalisation import declared_sweep, world_for
    from planodom.odometry import run_odometry
    from planodom.simulation.random_world import simulate_world, world_fields

    kernel = CUTS[0][2]
    for w in worlds:
        seen: list[tuple] = []

        def spy(*args: Any, seen: list = seen) -> Any:
            seen.append(args)
            return kernel(*args)

        world = world_for(w)
        run = world_fields(world, simulate_world(world, noise, n_epochs=epochs, all_fields=True))
        cfg = declared_sweep(world, PlanodomConfig())
        run_odometry(run, cfg)  # untimed: caches warm
        association.sda_kernel = spy
        run_odometry(run, cfg)
        association.sda_kernel = kernel
        for args in seen:  # the same pairs both ways
            assert kernel(*args)[1].tobytes() == former_sda(*args)[1].tobytes()
        best = {}
        for name, fn in (("former", former_sda), ("cuts", kernel)):
            rounds = []
            for _ in range(5):
                c0 = time.process_time()
                for _ in range(10):
                    for args in seen:
                        fn(*args)
                rounds.append((time.process_time() - c0) / 10)
            best[name] = min(rounds)
        per = {k: 1e6 * v / len(seen) for k, v in best.items()}
        saved = 1e6 * (best["former"] - best["cuts"]) / epochs
        print(f"world {w}: {len(seen)} calls ({len(seen) / epochs:.2f} an epoch), us a call "
              f"former {per['former']:.1f} cuts {per['cuts']:.1f}, saved {saved:.1f} us an epoch",
              flush=True)  # fmt: skip


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
