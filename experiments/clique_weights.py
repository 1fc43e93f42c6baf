"""The loop hypotheses' clique under both weights, lap by lap (issue 14).

For each lap (one lap of a procedural world, the odometry and relative poses of
``planodom experiment loops``), the batch with loop closure is built up to its clique
(:func:`planodom.smoothing.loop_gate.consistent_hypotheses`) and stopped there: one line
per loop hypothesis (factors, current and old epochs, the factors' horizontal error
against the truth), then the hypotheses kept and the map ties removed under
``smoothing.loop_consistency_weight`` "factors" and "revisits". Where both keep the same
the lap's outputs are the same under both (the clique's removals are its only effect);
where they differ, run ``experiments/wrong_ties.py`` with each.

    uv run python experiments/clique_weights.py '{JSON_CONFIG_CHANGES}' 32:0.02 2:0.02 ...
"""

from __future__ import annotations

import json
import sys

import gtsam
import numpy as np

import planodom.smoothing.batch as batch
import planodom.smoothing.loop_gate as loop_gate
from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import world_for
from planodom.geometry import invert_transform
from planodom.odometry import run_odometry
from planodom.simulation.random_world import simulate_world, world_fields
from planodom.smoothing.run import smoothing_config, smoothing_relatives

WEIGHTS = ("factors", "revisits")


class _Stop(Exception):
    """Raised once the clique has been compared (the solve is not needed)."""


def _compare(builder, graph, gaussian, gt, out: dict) -> None:
    """Each weight's kept hypotheses and removed ties into ``out``, flags restored."""
    fs = [f for f in getattr(builder, "loop_factors", []) if not f.removed]
    groups = sorted({f.group for f in fs})
    for g in groups:
        m = [f for f in fs if f.group == g]
        err = [float(np.linalg.norm(f.truth_error(gt)[3:])) for f in m]
        print(
            f"  hypothesis {g}: {len(m)} factors, epochs {m[0].epoch}-{m[-1].epoch} against "
            f"{sorted({f.old for f in m})}, {min(err):.2f}-{max(err):.2f} m off the truth"
        )
    reids = getattr(builder, "reidentifications", [])
    for weight in WEIGHTS:
        flags = [f.removed for f in builder.loop_factors], [r.removed for r in reids]
        builder.config = builder.config.model_copy(update={"loop_consistency_weight": weight})
        copy = gtsam.NonlinearFactorGraph()
        copy.push_back(graph)
        loop_gate.consistent_hypotheses(builder, copy, dict(gaussian))
        kept = [g for g in groups if not any(f.removed for f in fs if f.group == g)]
        out[weight] = (kept, sum(r.removed for r in reids) - sum(flags[1]))
        for f, v in zip(builder.loop_factors, flags[0], strict=True):
            f.removed = v
        for r, v in zip(reids, flags[1], strict=True):
            r.removed = v


def lap(index: int, noise: float, changes: dict) -> dict:
    """{weight: (kept hypotheses, map ties removed)} of one lap."""
    world = world_for(index)
    full = simulate_world(world, noise, n_epochs=None, all_fields=True)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    cfg = PlanodomConfig()
    odo = run_odometry(world_fields(world, full), smoothing_config(cfg))
    relatives = smoothing_relatives(odo, cfg)
    out: dict = {}

    def stop(builder, graph, gaussian):
        _compare(builder, graph, gaussian, gt, out)
        raise _Stop

    batch.consistent_hypotheses = stop  # this process only
    run_cfg = cfg.updated(
        {"smoothing.loop_closure": True, "smoothing.compute_covariances": False, **changes}
    )
    try:
        batch.smooth_batch(odo.planes, relatives, run_cfg)
    except _Stop:
        pass
    return out


def main(argv: list[str]) -> None:
    changes = json.loads(argv[0])
    for spec in argv[1:]:
        world, noise = spec.split(":")
        print(f"world {world} at {noise} m", flush=True)
        out = lap(int(world), float(noise), changes)
        same = "same" if len({repr(out.get(w)) for w in WEIGHTS}) == 1 else "DIFFERENT"
        print(
            "  kept (hypotheses, map ties removed): "
            + ", ".join(f"{w} {out.get(w)}" for w in WEIGHTS)
            + f": {same}",
            flush=True,
        )


if __name__ == "__main__":
    main(sys.argv[1:])
