"""Which stage loses a built-in scene's step when its motion is known (issue 11, INDOOR3).

Per built-in scene and noise (``planodom run --scenario`` defaults, as
``builtin_scenes.py``) and per step ``k - 1 -> k`` of ``--steps A B`` (and, with
``--unresolved``, every step the default odometry leaves unresolved), both epochs are
extracted from their points deskewed with the truth (``--deskew exact``: the oracle's
:func:`planodom.oracle.deskewed_points`; ``centre``: the true mean twist over the
epoch's points, what a perfect constant-twist deskew gives) and solved with the true
step as the prior. The step is put in the first stage that loses it:

- ``not formed``: the two epochs' planes share no two non-parallel true surfaces
  (labels, for measuring only); the oracle's surfaces (at least 100 points) each epoch
  misses are put down to the 2D-rig grouping's rule that drops them
  (``builtin_unresolved.missed_rules``: one ring, no seed pair, gap rule, RMS, other);
- ``no LDA pair``: they share a pair but the lenient association (LDA) finds none;
- ``consensus refuses``: LDA pairs, but the step is unresolved;
- ``degenerate``: the rotation is measured, the translation not;
- ``ok``.

Per step: the stage, planes / distinct true surfaces of both epochs, the oracle's status
and, where the planes were not formed, the rules. ``--world W`` takes world ``W`` of
``planodom experiment generalisation`` (``world_for``; 150 epochs with ``--unresolved``,
else to the last step) instead of a built-in scene.

    uv run python experiments/stage_loss.py --scene random-indoor --noise 0.02 --steps 490 500
    uv run python experiments/stage_loss.py --world 292 --noise 0.006 --steps 20 36
    uv run python experiments/stage_loss.py --scene random-indoor --noise 0.02 --unresolved
"""

from __future__ import annotations

import argparse
import collections
import dataclasses

import numpy as np
from builtin_scenes import config_with, simulated
from builtin_unresolved import (
    MIN_SURFACE_POINTS,
    captured_grouping,
    has_pair,
    labelled_traces,
    missed_rules,
)
from turn_lag import centre_twist

from planodom.angles import radians
from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import declared_sweep, world_for
from planodom.extraction.pipeline import extract
from planodom.extraction.rig2d import connect
from planodom.geometry import invert_transform
from planodom.odometry import run_odometry
from planodom.odometry.solver import estimate_relative_pose
from planodom.oracle import deskewed_points, epoch_moments, relative_pose
from planodom.simulation.random_world import simulate_world


def true_planes(sim, k: int, config: PlanodomConfig, deskew: str):  # noqa: ANN001, ANN201
    """Epoch ``k``'s planes, deskewed with the truth (``deskew``: exact or centre)."""
    scan = sim.scans[k]
    if deskew == "exact":
        moved = dataclasses.replace(scan, points=deskewed_points(scan, sim.trajectory,
                                                                 float(sim.times[k])))  # fmt: skip
        return extract(moved, config.extraction, np.zeros(6), sim.rig.sensor_origins).planes
    twist = centre_twist(sim, k)
    return extract(scan, config.extraction, twist, sim.rig.sensor_origins).planes


def stage(sim, k: int, config: PlanodomConfig, deskew: str, oracle) -> dict:  # noqa: ANN001
    """The row of step ``k - 1 -> k`` (module docstring)."""
    normals = {s.id: s.normal for s in sim.scene.surfaces}
    cos_par = float(np.cos(radians(config.association.parallel_angle_deg)))
    a, b = (true_planes(sim, j, config, deskew) for j in (k - 1, k))
    ids_a, ids_b = ({p.truth_id for p in x} for x in (a, b))
    prior = invert_transform(sim.poses[k - 1]) @ sim.poses[k]
    est = estimate_relative_pose(a, b, config, prior)
    status = str(est.status)
    n_lda = len(est.diagnostics.lda) if est.diagnostics is not None else 0
    if not has_pair(ids_a & ids_b, normals, cos_par):
        kind = "not formed"
    elif n_lda == 0:
        kind = "no LDA pair"
    elif status == "unresolved":
        kind = "consensus refuses"
    else:
        kind = status
    row = {"step": k, "stage": kind, "status": status, "lda": n_lda,
           "prev": f"{len(a)}/{len(ids_a)}", "curr": f"{len(b)}/{len(ids_b)}",
           "oracle": oracle[k], "rules": collections.Counter()}  # fmt: skip
    if kind == "not formed":
        for j in (k - 1, k):
            row["rules"].update(missed_rules(sim, j, config))
    return row


def oracle_statuses(sim, steps: list[int]) -> dict[int, str]:  # noqa: ANN001
    """The oracle's status of each step of ``steps`` (from its two epochs' moments)."""
    out = {}
    for k in steps:
        m = [epoch_moments(sim.scans[j], sim.trajectory, float(sim.times[j]), sim.scene)
             for j in (k - 1, k)]  # fmt: skip
        prior = invert_transform(sim.poses[k - 1]) @ sim.poses[k]
        out[k] = str(relative_pose(m[0], m[1], prior).status)
    return out


def detail(sim, k: int, config: PlanodomConfig) -> None:  # noqa: ANN001
    """``--detail K``: epoch ``K`` exactly deskewed; per oracle surface (at least
    ``MIN_SURFACE_POINTS`` points) whether it was found, its normal's z, and its traces
    (ring, points, length m, range m of the centroid); per pair of its traces of two rings
    their crossing angle (deg) and the distance between their centre lines (m)."""
    with captured_grouping() as captured:
        scan = sim.scans[k]
        moved = dataclasses.replace(scan, points=deskewed_points(scan, sim.trajectory,
                                                                 float(sim.times[k])))  # fmt: skip
        found = extract(moved, config.extraction, np.zeros(6), sim.rig.sensor_origins)
    got = {p.truth_id for p in found.planes}
    tr, label, p = labelled_traces(captured, moved.label)
    print(f"epoch {k}: sigma {p.sigma_m * 100:.2f} cm, tol {p.tol_m * 100:.2f} cm, rms limit "
          f"{p.max_rms_m * 100:.2f} cm; found {sorted(got)}")  # fmt: skip
    m = epoch_moments(scan, sim.trajectory, float(sim.times[k]), sim.scene)
    for sid, n_pts, normal in zip(m.ids, m.count, m.normal, strict=True):
        if n_pts < MIN_SURFACE_POINTS:
            continue
        own = np.flatnonzero((label == sid) & (tr.count >= p.min_trace_points))
        cells = [f"r{tr.ring[t]} {tr.count[t]}p {tr.hi[t] - tr.lo[t]:.1f}m "
                 f"@{np.linalg.norm(tr.centroid[t]):.1f}m" for t in own]  # fmt: skip
        print(f"  surface {sid:3d} {'FOUND' if sid in got else 'missed'} nz {normal[2]:+.2f} "
              f"{n_pts} points; traces: {'; '.join(cells)}")  # fmt: skip
        for a, i in enumerate(own):
            for j in own[a + 1 :]:
                if tr.ring[i] == tr.ring[j]:
                    continue
                sin_a = float(np.linalg.norm(np.cross(tr.direction[i], tr.direction[j])))
                ang = np.degrees(np.arcsin(min(1.0, sin_a)))
                ends = [tr.centroid[t] + tr.direction[t] * np.array([[tr.lo[t]], [tr.hi[t]]])
                        for t in (i, j)]  # fmt: skip
                gap = connect.segment_distance(ends[0][0], ends[0][1], ends[1][0], ends[1][1])
                print(f"      r{tr.ring[i]}-r{tr.ring[j]} ({tr.count[i]}p, {tr.count[j]}p): "
                      f"cross {ang:5.1f} deg, lines {gap:5.2f} m apart")  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="random-indoor")
    ap.add_argument("--world", type=int, default=None, help="a generalisation world")
    ap.add_argument("--noise", default="0.02")
    ap.add_argument("--steps", type=int, nargs=2, default=None)
    ap.add_argument("--unresolved", action="store_true", help="the run's unresolved steps")
    ap.add_argument("--deskew", choices=("exact", "centre"), default="exact")
    ap.add_argument(
        "--set", nargs="*", action="extend", default=[], help="config overrides key=value"
    )
    ap.add_argument("--detail", type=int, nargs="*", default=[], help="epochs to show")
    args = ap.parse_args()
    config = config_with(args.set)
    if args.world is None:
        sim, _ = simulated(args.scene, args.noise)
    else:
        world = world_for(args.world)
        ends = [*(args.steps or [])[1:], *args.detail]
        last = 150 if args.unresolved or not ends else max(ends) + 1
        sim = simulate_world(world, float(args.noise), n_epochs=last, all_fields=True)
        config = declared_sweep(world, config)
        args.scene = f"world {args.world}"
    for k in args.detail:
        detail(sim, k, config)
    if args.detail and not (args.steps or args.unresolved):
        return
    steps = set(range(args.steps[0], args.steps[1] + 1)) if args.steps else set()
    if args.unresolved:
        run = run_odometry(sim, config, sim.rig)
        steps |= {k for k, s in enumerate(run.statuses) if s == "unresolved" and k > 0}
        print(f"default run: {sum(s == 'unresolved' for s in run.statuses)} unresolved")
    oracle = oracle_statuses(sim, sorted(steps))
    rows = [stage(sim, k, config, args.deskew, oracle) for k in sorted(steps)]
    for r in rows:
        rules = ", ".join(f"{n} {w}" for w, n in r["rules"].most_common())
        sizes = f"planes/surfaces {r['prev']:>6s} {r['curr']:>6s}"
        print(f"{r['step']:4d} {r['stage']:18s} {r['status']:10s} lda {r['lda']:3d} {sizes} "
              f"oracle {r['oracle']:10s} {rules}")  # fmt: skip
    stages = collections.Counter((r["stage"], r["oracle"]) for r in rows)
    print(f"{args.scene} {args.noise}, deskew {args.deskew}, {len(rows)} steps:")
    for (kind, orc), n in sorted(stages.items()):
        print(f"  {n:4d}  {kind}  (oracle {orc})")
    tally: collections.Counter = collections.Counter()
    for r in rows:
        tally.update(r["rules"])
    print(f"  oracle planes (>= {MIN_SURFACE_POINTS} points) of the not-formed steps' epochs:")
    for rule, n in tally.most_common():
        print(f"  {n:6d}  {'found' if rule == 'found' else 'missed: ' + rule}")


if __name__ == "__main__":
    main()
