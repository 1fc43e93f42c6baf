"""The exact glue cuts call by call: each cut's CPU a call, as it is and as it was (the
former expressions of ``bench_glue_cuts.py``, SPEED2D8, or with ``--cuts speed2d9``
``bench_glue_cuts9.py``), on calls captured from runs.

For each world (the 2D rig's default odometry, 150 epochs), an untimed run, then one run
with every cut function wrapped to record its arguments; the recorded calls are then
replayed ``--replays`` times per trial with the cut and with its former expression, best of
``--trials`` (process time; warm: the calls repeat, so the caches are hotter than in a run).
Per cut: calls an epoch, us a call both ways, and the us saved an epoch.

    uv run python experiments/bench_glue_calls.py --noise 0.02 --worlds 162 168
    uv run python experiments/bench_glue_calls.py --cuts speed2d9 --worlds 162 168
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import importlib  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from types import ModuleType  # noqa: E402
from typing import Any  # noqa: E402

from planodom.config import PlanodomConfig  # noqa: E402
from planodom.experiments.generalisation import declared_sweep, world_for  # noqa: E402
from planodom.odometry import run_odometry  # noqa: E402
from planodom.simulation.random_world import simulate_world, world_fields  # noqa: E402

Calls = dict[str, list[tuple[tuple[Any, ...], dict[str, Any]]]]


def _recording(name: str, fn: Callable[..., Any], calls: Calls) -> Callable[..., Any]:
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        calls.setdefault(name, []).append((args, kwargs))
        return fn(*args, **kwargs)

    return wrapper


#: the cuts and their former expressions (the scripts beside this one in experiments/)
CUT_SETS = {"speed2d8": "bench_glue_cuts", "speed2d9": "bench_glue_cuts9"}


def captured(cuts: ModuleType, worlds: list[int], noise: float, epochs: int) -> Calls:
    """The cut functions' calls in one run of each world (after an untimed one)."""
    calls: Calls = {}
    for w in worlds:
        world = world_for(w)
        cfg = declared_sweep(world, PlanodomConfig())
        run = world_fields(world, simulate_world(world, noise, n_epochs=epochs, all_fields=True))
        cuts.use("cuts")
        run_odometry(run, cfg)
        for obj, name, fn in cuts.CUTS:
            setattr(obj, name, _recording(name, fn, calls))
        run_odometry(run, cfg)
        cuts.use("cuts")
    return calls


def per_call(fn: Callable[..., Any], calls: list, replays: int, trials: int) -> float:
    """CPU us a call of ``fn`` over the recorded ``calls``, best of ``trials``."""
    best = float("inf")
    for _ in range(trials):
        c0 = time.process_time()
        for _ in range(replays):
            for args, kwargs in calls:
                fn(*args, **kwargs)
        best = min(best, (time.process_time() - c0) / replays / len(calls))
    return 1e6 * best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--worlds", type=int, nargs="+", default=[162, 168])
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--replays", type=int, default=10)
    ap.add_argument("--trials", type=int, default=5)
    ap.add_argument("--cuts", choices=sorted(CUT_SETS), default="speed2d8")
    args = ap.parse_args()
    cuts = importlib.import_module(CUT_SETS[args.cuts])
    calls = captured(cuts, args.worlds, args.noise, args.epochs)
    epochs = args.epochs * len(args.worlds)
    new = {name: fn for _, name, fn in cuts.CUTS}
    former = {name: fn for _, name, fn in cuts.FORMER}
    total = 0.0
    for name, recorded in calls.items():
        us_former = per_call(former[name], recorded, args.replays, args.trials)
        us_cut = per_call(new[name], recorded, args.replays, args.trials)
        rate = len(recorded) / epochs
        total += (us_former - us_cut) * rate
        print(
            f"{name:20s} calls an epoch {rate:5.2f} | former {us_former:6.2f} us cuts "
            f"{us_cut:6.2f} us | saved {(us_former - us_cut) * rate:6.2f} us an epoch"
        )
    print(f"total saved {total:.1f} us an epoch")


if __name__ == "__main__":
    main()
