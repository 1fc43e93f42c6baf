"""Why each epoch of a 2D-rig world's unresolved stretch is unresolved, against the truth
(issue 11, GAP190).

One world (``world_for``, as ``planodom experiment generalisation`` runs it) is run with
the default config (or the ``--set`` overrides) for ``B + 2`` epochs. Per epoch of
``--steps A B``:

- ``odo``: the odometry's status, its reference epoch (``results[k].prev``), ``gate``
  when ``odometry.degenerate_gate`` reported a degenerate step unresolved, and the true
  surfaces (``Plane.truth_id``) of its planes and of its reference's;
- ``true twist``: the surfaces the extraction finds with the true twist over the
  epoch's points (the best a deskewing can give it);
- ``oracle``: its status against the epoch before (:func:`planodom.oracle.relative_pose`,
  from the true step) and its planes: ``id:points(width m)``, every labelled surface with
  at least 20 points spread at least 0.2 m across (the oracle's plane test);
- ``class``: the first that fits: ``truth: one plane`` (the oracle's planes of the
  epoch hold no two non-parallel surfaces, normals more than ``association.
  parallel_angle_deg`` apart: no plane odometry measures the rotation), ``truth: no
  common pair`` (the epoch and the one before share no such pair of oracle planes),
  ``extraction`` (the truth has a common pair, the odometry's planes of the epoch hold
  none), ``gate``, ``reference`` (the odometry's planes share no pair of surfaces with its
  reference's), ``association`` (they do, and the step was not found).

    uv run python experiments/gap_trace.py --world 190 --noise 0.02 --steps 48 86
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np
from builtin_scenes import config_with

from planodom.experiments.generalisation import declared_sweep, world_for
from planodom.extraction import extract_planes
from planodom.geometry import invert_transform, se3_log
from planodom.odometry import run_odometry
from planodom.oracle import epoch_moments, relative_pose
from planodom.simulation.random_world import simulate_world, world_fields


def centre_twist(sim: Any, k: int) -> np.ndarray:
    """(6,) the true mean body twist over epoch ``k``'s points' time span (rad/s, m/s)."""
    t = np.asarray(sim.scans[k].t)
    a, b = sim.times[k] + float(t.min()), sim.times[k] + float(t.max())
    Ta, Tb = sim.trajectory.pose(a), sim.trajectory.pose(b)
    return se3_log(invert_transform(Ta) @ Tb) / (b - a)


def has_pair(ids: set[int], normals: dict[int, np.ndarray], cos_parallel: float) -> bool:
    """Whether the true surfaces ``ids`` hold two non-parallel ones (either orientation)."""
    n = [normals[i] for i in sorted(ids) if i in normals]
    return any(abs(float(a @ b)) < cos_parallel for i, a in enumerate(n) for b in n[i + 1 :])


def widths(m: Any) -> list[float]:
    """The in-plane minor extent (m) of each oracle plane, as its plane test computes it."""
    return [2.0 * np.sqrt(max(np.linalg.eigvalsh(S)[1], 0.0) / N)
            for S, N in zip(m.scatter, m.count, strict=True)]  # fmt: skip


def epoch_class(
    own: set[int], ref: set[int], truth: set[int], truth_prev: set[int], gate: bool,
    pair: Any,
) -> str:  # fmt: skip
    """The class of an unresolved epoch (module docstring); ``pair(ids) -> bool``."""
    if not pair(truth):
        return "truth: one plane"
    if not pair(truth & truth_prev):
        return "truth: no common pair"
    if not pair(own):
        return "extraction"
    if gate:
        return "gate"
    return "reference" if not pair(own & ref) else "association"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--world", type=int, default=190)
    ap.add_argument("--noise", type=float, default=0.02)
    ap.add_argument("--steps", type=int, nargs=2, default=[48, 86])
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = ap.parse_args()
    a, b = args.steps
    world = world_for(args.world)
    sim = simulate_world(world, args.noise, n_epochs=b + 2, all_fields=True)
    config = declared_sweep(world, config_with(args.set))
    odo = run_odometry(world_fields(world, sim), config)
    normals = {s.id: np.asarray(s.normal) for s in world.scene.surfaces}
    cos_par = float(np.cos(np.radians(config.association.parallel_angle_deg)))

    def pair(ids: set[int]) -> bool:
        return has_pair(ids, normals, cos_par)

    moments = {k: epoch_moments(sim.scans[k], world.trajectory, float(sim.times[k]),
                                world.scene) for k in range(max(a - 1, 0), b + 1)}  # fmt: skip
    tally: dict[str, int] = {}
    for k in range(max(a, 1), b + 1):
        r, m = odo.results[k], moments[k]
        assert r is not None  # only the first epoch has no result
        own = {p.truth_id for p in odo.planes[k]}
        ref = {p.truth_id for p in odo.planes[r.prev]}
        true_step = invert_transform(sim.poses[k - 1]) @ sim.poses[k]
        orc = relative_pose(moments[k - 1], m, true_step)
        found = extract_planes(sim.scans[k], config.extraction, twist=centre_twist(sim, k),
                               sensor_origins=sim.rig.sensor_origins)  # fmt: skip
        surf = " ".join(f"{i}:{n}({w:.1f})" for i, n, w in zip(m.ids, m.count, widths(m),
                                                               strict=True))  # fmt: skip
        gate = bool(getattr(r, "inconsistent", False))
        cls = ""
        if r.status.name == "UNRESOLVED":
            truth, prev = {int(i) for i in m.ids}, {int(i) for i in moments[k - 1].ids}
            cls = epoch_class(own, ref, truth, prev, gate, pair)
            tally[cls] = tally.get(cls, 0) + 1
        exact = sorted(p.truth_id for p in found)
        print(f"{k:3d} odo {r.status.name[:5]:5s} ref {r.prev:3d}{' gate' if gate else ''} "
              f"{sorted(own)} vs {sorted(ref)} | true twist {exact} | oracle "
              f"{orc.status[:5]} {surf} | {cls}")  # fmt: skip
    print("unresolved epochs by class:", tally)


if __name__ == "__main__":
    main()
