"""``odometry.motion_model`` before/after on the generalisation worlds (issue 11).

``uv run python experiments/motion_model_ab.py W [W ...] [--noise 0.006 0.02]
[--epochs 150] [--handheld] [--set KEY=VALUE ...]``: per world and noise, one simulation
(as ``planodom experiment generalisation`` makes it, with its declared sweep), planodom
run twice on it: the default configuration and the same with ``odometry.motion_model:
nonholonomic`` (or the ``--set`` overrides). One line each: rotation and xy rms per epoch
(deg, cm), ATE (xy, origin-aligned, m), unresolved and degenerate epochs, and whether
the two runs' poses are bit-identical. Before and after share the simulation and run in
the same process, so only the option differs.
"""

from __future__ import annotations

import argparse

import numpy as np
import yaml

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import (
    MethodRun,
    _metrics,
    declared_sweep,
    world_for,
)
from planodom.geometry import invert_transform
from planodom.odometry import run_odometry
from planodom.simulation.random_world import simulate_world, world_fields


def _run(world, full, cfg: PlanodomConfig, noise: float, gt: np.ndarray) -> MethodRun:
    odo = run_odometry(world_fields(world, full), declared_sweep(world, cfg))
    fam = world.description["family"]
    mr = MethodRun(world.seed, world.kind, fam, noise, "planodom", odo.poses, odo.statuses,
                   sum(odo.seconds.values()), gt)  # fmt: skip
    mr.metrics = _metrics(mr, None)
    return mr


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("worlds", type=int, nargs="+")
    ap.add_argument("--noise", type=float, nargs="+", default=[0.006, 0.02])
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("--handheld", action="store_true")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    a = ap.parse_args()
    changes = {k: yaml.safe_load(v) for k, v in (s.split("=", 1) for s in a.set)}
    after = PlanodomConfig().updated(changes or {"odometry.motion_model": "nonholonomic"},
                                     source="motion_model_ab")  # fmt: skip
    print("world noise_mm run rot_rms_deg xy_rms_cm ate_xy_m unresolved degenerate identical")
    for w in a.worlds:
        world = world_for(w, "handheld" if a.handheld else "vehicle")
        for noise in a.noise:
            full = simulate_world(world, noise, n_epochs=a.epochs, all_fields=True)
            gt = invert_transform(full.poses[0])[None] @ full.poses
            runs = [_run(world, full, c, noise, gt) for c in (PlanodomConfig(), after)]
            same = bool(np.array_equal(runs[0].poses, runs[1].poses))
            for name, r in zip(("before", "after"), runs, strict=True):
                m = r.metrics
                print(f"{w} {noise * 1000:g} {name} {m['rot_rms_deg']:.4g} "
                      f"{m['xy_rms_m'] * 100:.4g} {m['ate_xy_m']:.4g} {m['unresolved']:g} "
                      f"{m['degenerate']:g} {same}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
