"""SPEED2D12's compiled per-scan passes (:mod:`planodom.extraction.scan_prep`: the ring
order, the ring count, the points' checks) against the numpy forms they replace, in one
process, with KISS-ICP on the same scans.

The 2D rig's default odometry runs each world's simulated run as it is ("cuts") and as
it was ("former": each pass answered None, so the numpy forms run), alternating,
``--reps`` times each after an untimed warm-up of both, and KISS-ICP on the same scans
(``bench_glue_cuts.py``'s loop: the fastest repetition of each counts, process time; the
two variants' poses must be the same bits, checked on every repetition). ``--calls``
instead counts the passes' calls in one run of each world (the memo's misses: about one
of each an epoch) and replays the three entry points on the run's scans, unmemoised, 10
times a round, best of 5 rounds, process time, both ways: microseconds a scan and saved
an epoch, less moved by the load.

    uv run --extra baselines python experiments/bench_scan_prep.py --noise 0.02 \\
        --epochs 150 --worlds 160 162 164 168 --reps 5
    uv run python experiments/bench_scan_prep.py --calls --noise 0.02 --worlds 162 168
"""

from __future__ import annotations

import inspect
import sys
import time
from collections import Counter
from typing import Any

import bench_glue_cuts

import planodom.extraction.pipeline as pipeline
import planodom.extraction.rig2d.segments as segments


def _none(*args: Any) -> None:
    """A pass that does not apply: the numpy form answers."""
    return None


#: (object, attribute, former): what "former" puts back
FORMER = (
    (segments, "compiled_ring_order", _none),
    (pipeline, "points_times_finite", _none),
    (pipeline, "compiled_count_rings", _none),
)
CUTS = bench_glue_cuts.cuts_of(FORMER)

#: the entry points replayed by ``--calls`` (unmemoised), by name
_RING_ORDER = inspect.unwrap(segments.ring_order)
_COUNT_RINGS = inspect.unwrap(pipeline.count_rings)
_CHECKS = inspect.unwrap(pipeline._check_points_times)
ENTRIES = {
    "ring order": lambda s: _RING_ORDER(s.ring, s.t),
    "ring count": lambda s: _COUNT_RINGS(s.ring),
    "points' checks": lambda s: _CHECKS(s.points, s.t),
}


def _best(scans: list, fn: Any, variant: str) -> float:
    """Seconds of one pass of ``fn`` over ``scans``, best of 5 rounds of 10."""
    bench_glue_cuts.use(variant, CUTS, FORMER)
    rounds = []
    for _ in range(5):
        c0 = time.process_time()
        for _ in range(10):
            for s in scans:
                fn(s)
        rounds.append((time.process_time() - c0) / 10)
    bench_glue_cuts.use("cuts", CUTS, FORMER)
    return min(rounds)


def calls(worlds: list[int], noise: float, epochs: int) -> None:
    """Print, per world, the passes' calls an epoch in a run and their CPU a scan."""
    from planodom.config import PlanodomConfig
    from planodom.experiments.generalisation import declared_sweep, world_for
    from planodom.odometry import run_odometry
    from planodom.simulation.random_world import simulate_world, world_fields

    for w in worlds:
        world = world_for(w)
        run = world_fields(world, simulate_world(world, noise, n_epochs=epochs, all_fields=True))
        cfg = declared_sweep(world, PlanodomConfig())
        run_odometry(run, cfg)  # untimed: caches warm
        n: Counter[str] = Counter()
        for obj, name, fn in CUTS:

            def counted(*args: Any, fn: Any = fn, name: str = name, n: Counter = n) -> Any:
                n[name] += 1
                return fn(*args)

            setattr(obj, name, counted)
        run_odometry(run, cfg)
        bench_glue_cuts.use("cuts", CUTS, FORMER)
        counts = ", ".join(f"{k} {v / epochs:.2f}" for k, v in n.items())
        print(f"world {w}: calls an epoch: {counts}", flush=True)
        scans = list(run.scans)
        total = 0.0
        for label, fn in ENTRIES.items():
            best = {v: _best(scans, fn, v) for v in ("former", "cuts")}
            per = {k: 1e6 * v / len(scans) for k, v in best.items()}
            total += per["former"] - per["cuts"]
            print(f"world {w} {label}: us a scan former {per['former']:.1f} cuts "
                  f"{per['cuts']:.1f}", flush=True)  # fmt: skip
        print(f"world {w}: saved {total:.1f} us a scan (one of each an epoch)", flush=True)


if __name__ == "__main__":
    if "--calls" in sys.argv:
        sys.argv.remove("--calls")
        import argparse

        ap = argparse.ArgumentParser()
        ap.add_argument("--worlds", type=int, nargs="+", default=[162, 168])
        ap.add_argument("--noise", type=float, default=0.02)
        ap.add_argument("--epochs", type=int, default=150)
        a = ap.parse_args()
        calls(a.worlds, a.noise, a.epochs)
        sys.exit(0)
    bench_glue_cuts.main(CUTS, FORMER, __doc__)
