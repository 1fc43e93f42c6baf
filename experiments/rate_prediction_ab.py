"""Extractions an epoch and CPU time of the 2D rig's odometry with ``odometry.
rate_prediction`` constant (the default) and autoregressive, on the same simulated epochs.

Each world is simulated once per noise; the odometry then runs with each setting in turn,
alternating (off, on, on, off with ``--repeats 2``; one run of each first, untimed, to warm
up), timed by ``time.process_time``, its extractions counted (every call of
``PlaneOdometry._extract``: the epoch's passes, its retries, the reference's refreshes).
Docs/RESULTS.md, PREDICT:

    uv run python experiments/rate_prediction_ab.py --worlds 0 2 4 6 8 10 12 14 16 18
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402
import yaml  # noqa: E402

import planodom.odometry.odometry as odo_mod  # noqa: E402
from planodom.config import PlanodomConfig  # noqa: E402
from planodom.experiments.generalisation import declared_sweep, world_for  # noqa: E402
from planodom.odometry import run_odometry  # noqa: E402
from planodom.simulation.random_world import simulate_world, world_fields  # noqa: E402

COUNT = [0]
WARM: list = []


def _counting() -> None:
    real = odo_mod.PlaneOdometry._extract

    def extract(self, *a, **k):
        COUNT[0] += 1
        return real(self, *a, **k)

    odo_mod.PlaneOdometry._extract = extract  # type: ignore[method-assign]


def _run(sim, cfg: PlanodomConfig) -> tuple[float, int, np.ndarray]:
    """(CPU s, extractions, poses (E, 4, 4)) of one run."""
    COUNT[0] = 0
    t0 = time.process_time()
    run = run_odometry(sim, cfg)
    return time.process_time() - t0, COUNT[0], np.asarray(run.poses)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--worlds", type=int, nargs="+", default=[0, 2, 4])
    ap.add_argument("--noise", type=float, nargs="+", default=[0.006, 0.02])
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument(
        "--set", nargs="*", action="extend", default=[], help="more KEY=VALUE (yaml) for 'on'"
    )
    args = ap.parse_args()
    _counting()
    on = {"odometry.rate_prediction": "autoregressive"}
    on |= {kv.split("=", 1)[0]: yaml.safe_load(kv.split("=", 1)[1]) for kv in args.set}
    for noise in args.noise:
        tot = {"off": [0.0, 0, 0], "on": [0.0, 0, 0]}
        for w in args.worlds:
            world = world_for(w)
            base = declared_sweep(world, PlanodomConfig())
            cfgs = {"off": base, "on": base.updated(on, source="rate_prediction_ab")}
            sim = world_fields(world, simulate_world(world, noise, args.epochs, all_fields=True))
            if not WARM:  # compile and warm the caches before any run is timed
                WARM.extend(_run(sim, cfgs[name]) for name in ("off", "on"))
            order = ["off", "on", "on", "off"] * args.repeats
            got: dict[str, list] = {"off": [], "on": []}
            for name in order[: 2 * args.repeats]:
                got[name].append(_run(sim, cfgs[name]))
            row = []
            for name in ("off", "on"):
                cpu = float(np.mean([g[0] for g in got[name]]))
                n = got[name][0][1]
                tot[name][0] += cpu
                tot[name][1] += n
                tot[name][2] += args.epochs
                row.append(
                    f"{name} {n / args.epochs:.2f} extr/epoch {1e3 * cpu / args.epochs:.2f} ms"
                )
            same = np.array_equal(got["off"][0][2], got["on"][0][2])
            print(
                f"noise {noise * 1e3:g} mm world {w}: " + ", ".join(row) + f" identical {same}",
                flush=True,
            )
        for name, (cpu, n, e) in tot.items():
            print(f"noise {noise * 1e3:g} mm total {name}: {n / e:.3f} extractions/epoch, "
                  f"{1e3 * cpu / e:.2f} ms/epoch CPU", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
