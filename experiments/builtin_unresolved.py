"""Why a built-in scene's epochs are unresolved, against the oracle (issue 11).

Per built-in scene and noise (``planodom run --scenario`` defaults, as
``builtin_scenes.py``), the odometry is run with every reference refresh logged, and each
unresolved epoch is put in the first class that fits:

- ``gate``: the solver found it degenerate, ``odometry.degenerate_gate`` reported it
  unresolved (its rate disagreed with the prediction);
- ``refresh shrank the reference``: while the epoch was registered, its reference was
  extracted again with the epoch's twist and came out with fewer surfaces;
- ``no pair in the epoch``: its planes hold no two non-parallel true surfaces;
- ``no common pair``: it shares no two non-parallel true surfaces with its reference;
- ``common pair``: it does, and the association / consensus found none.

Then both epochs (it and its reference) are extracted from their points deskewed exactly
(the oracle's :func:`planodom.oracle.deskewed_points`) and solved with the true motion as
the prior: ``exact: <status>``. With ``--why`` every surface the oracle has as a plane
(at least 100 points) in those epochs and the exact extraction misses is put down to the
2D-rig grouping's rule that drops it (:mod:`planodom.extraction.rig2d.grouping`): seen by
one ring, no seed pair (two rings crossing under ``min_cross_angle_deg``), the seed lost
to the gap rule (``plane_gap_m``), its RMS over ``max_rms_sigma_factor`` sigma, or other.

    uv run python experiments/builtin_unresolved.py --scenes random-indoor --noise 0.02 --why
    uv run python experiments/builtin_unresolved.py --set extraction.noise_estimate=range

With ``--part`` the scene is also run with the reference rule before GAPS5 (any epoch of
two planes is a reference, not only one with a non-parallel pair: ``KeptEpoch.has_pair``
replaced), and the first epoch where the two runs' poses part is printed with, per
stretch of epochs where either run's summed yaw error of its steps moves by more than
1 deg, both runs' sums (deg) and the statuses there.
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import dataclasses
import sys
from collections.abc import Iterator

import numpy as np
from builtin_scenes import SCENES, config_with, simulated

from planodom.angles import radians
from planodom.config import PlanodomConfig
from planodom.extraction.pipeline import extract
from planodom.extraction.rig2d import grouping, groups, path
from planodom.geometry import invert_transform
from planodom.metrics import ate
from planodom.odometry import kept_epoch, run_odometry
from planodom.odometry.odometry import PlaneOdometry
from planodom.odometry.solver import estimate_relative_pose
from planodom.oracle import deskewed_points, epoch_moments, run_oracle

#: Fewest labelled points of an oracle plane counted by ``--why``.
MIN_SURFACE_POINTS = 100


def logged_run(sim, config: PlanodomConfig):  # noqa: ANN001, ANN201
    """The odometry's run and, per epoch index, the surfaces (truth ids) of each
    reference refresh made while it was registered: [(before, after)]."""
    log: dict[int, list[tuple[set[int], set[int]]]] = collections.defaultdict(list)
    original = PlaneOdometry._refresh_reference

    def refresh(self: PlaneOdometry, twist: np.ndarray) -> bool:
        ref = self._reference()
        before = {p.truth_id for p in ref.planes}
        done = original(self, twist)
        if done:
            log[len(self.poses)].append((before, {p.truth_id for p in ref.planes}))
        return done

    PlaneOdometry._refresh_reference = refresh  # type: ignore[method-assign]
    try:
        return run_odometry(sim, config, sim.rig), log
    finally:
        PlaneOdometry._refresh_reference = original  # type: ignore[method-assign]


def has_pair(ids: set[int], normals: dict[int, np.ndarray], cos_parallel: float) -> bool:
    """Whether the true surfaces ``ids`` hold two non-parallel ones."""
    n = [normals[i] for i in ids if i in normals]
    return any(abs(a @ b) < cos_parallel for i, a in enumerate(n) for b in n[i + 1 :])


def exact_planes(sim, k: int, config: PlanodomConfig):  # noqa: ANN001, ANN201
    """Epoch ``k``'s extraction from its points deskewed exactly (a zero twist)."""
    scan = sim.scans[k]
    points = deskewed_points(scan, sim.trajectory, float(sim.times[k]))
    exact = dataclasses.replace(scan, points=points)
    return extract(exact, config.extraction, np.zeros(6), sim.rig.sensor_origins), exact


def classify(run, log, sim, config: PlanodomConfig, oracle) -> list[dict]:  # noqa: ANN001
    """One row per unresolved epoch (module docstring)."""
    normals = {s.id: s.normal for s in sim.scene.surfaces}
    cos_par = float(np.cos(radians(config.association.parallel_angle_deg)))
    rows = []
    for k, r in enumerate(run.results):
        if r is None or str(r.status) != "unresolved":
            continue
        own = {p.truth_id for p in run.planes[k]}
        ref = {p.truth_id for p in run.planes[r.prev]}
        shrank = any(len(after) < len(before) for before, after in log.get(k, []))
        if r.inconsistent:
            kind = "gate"
        elif shrank:
            kind = "refresh shrank the reference"
        elif not has_pair(own, normals, cos_par):
            kind = "no pair in the epoch"
        elif not has_pair(own & ref, normals, cos_par):
            kind = "no common pair"
        else:
            kind = "common pair"
        prior = invert_transform(sim.poses[r.prev]) @ sim.poses[k]
        a, b = (exact_planes(sim, j, config)[0].planes for j in (r.prev, k))
        status = str(estimate_relative_pose(a, b, config, prior).status)
        rows.append({"epoch": k, "prev": r.prev, "class": kind, "exact": status,
                     "oracle": oracle.statuses[k]})  # fmt: skip
    return rows


@contextlib.contextmanager
def captured_grouping() -> Iterator[dict]:
    """Within the block, every call of the 2D rig's ``path.group_segments`` records its
    ``segs``, ``params`` and further ``args`` in the dict yielded (the last call's)."""
    captured: dict = {}
    original = path.group_segments

    def capture(segs, params, *args):  # noqa: ANN001, ANN002, ANN202
        captured.update(segs=segs, params=params, args=args)
        return original(segs, params, *args)

    path.group_segments = capture
    try:
        yield captured
    finally:
        path.group_segments = original


def missed_rules(sim, k: int, config: PlanodomConfig) -> collections.Counter:  # noqa: ANN001
    """Per rule, the oracle's planes of epoch ``k`` the exact extraction misses (``--why``)."""
    with captured_grouping() as captured:
        found, exact = exact_planes(sim, k, config)
    got = {p.truth_id for p in found.planes}
    m = epoch_moments(sim.scans[k], sim.trajectory, float(sim.times[k]), sim.scene)
    want = [int(i) for i, c in zip(m.ids, m.count, strict=True) if c >= MIN_SURFACE_POINTS]
    tally: collections.Counter = collections.Counter(found=sum(i in got for i in want))
    missing = [i for i in want if i not in got]
    if missing and captured:
        tally.update(rule_of(captured, exact.label, missing))
    return tally


def labelled_traces(captured: dict, labels: np.ndarray):  # noqa: ANN201
    """The traces the grouping built from the ``captured`` segments (:func:`missed_rules`)
    and, per trace, its majority truth label: ``(TraceSet, label (T,), params)``."""
    segs, p = captured["segs"], captured["params"]
    parallel_deg, step = captured["args"][:2]
    S = len(segs)
    link = groups._LinkParams(float(p.tol_m), float(radians(parallel_deg)), float(step),
                              float(p.max_span_s), groups.LINK_BAND)  # fmt: skip
    err = groups._direction_error(float(p.sigma_m), segs.count, segs.length)
    lines = groups._SegmentLines(segs.ring, segs.sweep, np.zeros(S), np.zeros(S), segs.centroid,
                                 segs.direction, segs.length, err, segs.count, segs.scatter,
                                 segs.end0, segs.end1)  # fmt: skip
    trace_of = groups._link_segments(lines, link)
    ring, count, cen, scatter, direction, lo, hi, t_lo, t_hi = groups._trace_moments(
        lines, trace_of
    )
    err_t = groups._direction_error(float(p.sigma_m), count, hi - lo)
    tr = groups.TraceSet(trace_of, ring, count, cen, scatter, direction, lo, hi, err_t, t_lo, t_hi)
    lab = labels[segs.order]
    label = np.array([np.bincount(np.concatenate([lab[segs.starts[s] : segs.ends[s]]
                      for s in np.flatnonzero(trace_of == t)]) + 1).argmax() - 1
                      for t in range(len(count))])  # fmt: skip
    return tr, label, p


def rule_of(captured: dict, labels: np.ndarray, missing: list[int]) -> list[str]:
    """The grouping's rule that drops each surface of ``missing`` (module docstring), from
    the segments and parameters the extraction grouped with (``captured``)."""
    tr, label, p = labelled_traces(captured, labels)
    ring, count = tr.ring, tr.count.astype(float)
    seeds = grouping._seed_pairs(tr, p, count, count >= p.min_trace_points)
    member = grouping._membership(tr, p, count, count >= p.min_trace_points, seeds)
    out = []
    for surface in missing:
        if len(set(ring[label == surface])) < 2:
            out.append("seen by one ring")
            continue
        own = [s for s in range(len(seeds.i)) if label[seeds.i[s]] == label[seeds.j[s]] == surface]
        reasons = {_grown(tr, p, count, seeds, s, member) for s in own}
        out.append("no seed pair" if not own else "other" if "other" in reasons else
                   "gap rule" if reasons == {"gap rule"} else "rms" if reasons == {"rms"} else
                   " + ".join(sorted(reasons)))  # fmt: skip
    return out


def _grown(tr, p, count, seeds, s, member) -> str:  # noqa: ANN001
    """What the grouping's growth of seed ``s`` alone ends in: "gap rule" (the seed's
    second trace is cut off), "rms", "points" or "other" (a plane: taken by another
    group first, or dropped by a later test)."""
    members = member[s].copy()
    members[seeds.i[s]] = members[seeds.j[s]] = True
    available = np.ones(len(count), dtype=bool)
    grown, rms, total = grouping._grow(tr, p, count, seeds, s, members, available)
    if not (grown[seeds.i[s]] and grown[seeds.j[s]]):
        return "gap rule"
    return "rms" if rms > p.max_rms_m else "points" if total < p.min_points else "other"


def report(scene: str, noise: str, config: PlanodomConfig, why: bool) -> None:
    """The classes of one scene's unresolved epochs (and ``why``'s rules) to stdout."""
    sim, _ = simulated(scene, noise)
    run, log = logged_run(sim, config)
    oracle = run_oracle(sim.scans, sim.times, sim.trajectory, sim.scene)
    rows = classify(run, log, sim, config, oracle)
    print(f"{scene} {noise}: {len(rows)} unresolved; the oracle's statuses there: "
          f"{dict(collections.Counter(r['oracle'] for r in rows))}")  # fmt: skip
    classes = collections.Counter((r["class"], r["exact"]) for r in rows)
    for (kind, exact), n in sorted(classes.items()):
        print(f"  {n:4d}  {kind}  (exact: {exact})")
    if why:
        tally: collections.Counter = collections.Counter()
        for k in sorted({r["epoch"] for r in rows} | {r["prev"] for r in rows}):
            tally.update(missed_rules(sim, k, config))
        print(f"  oracle planes (>= {MIN_SURFACE_POINTS} points) in those epochs and their "
              "references, exact extraction:")  # fmt: skip
        for rule, n in tally.most_common():
            print(f"  {n:6d}  {'found' if rule == 'found' else 'missed: ' + rule}")
    sys.stdout.flush()


def step_yaw_errors(poses: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """(E,) each step's yaw error (deg; 0 first): ``inv(true step) @ step``."""
    out = np.zeros(len(poses))
    for k in range(1, len(poses)):
        e = invert_transform(invert_transform(truth[k - 1]) @ truth[k])
        e = e @ invert_transform(poses[k - 1]) @ poses[k]
        out[k] = np.degrees(np.arctan2(e[1, 0], e[0, 0]))
    return out


def parting(scene: str, noise: str, config: PlanodomConfig) -> None:
    """``--part`` (module docstring) to stdout."""
    sim, truth = simulated(scene, noise)
    new = run_odometry(sim, config, sim.rig)
    rule = kept_epoch.KeptEpoch.has_pair
    kept_epoch.KeptEpoch.has_pair = lambda self, association: len(self.planes) >= 2  # type: ignore[method-assign]
    try:
        old = run_odometry(sim, config, sim.rig)
    finally:
        kept_epoch.KeptEpoch.has_pair = rule  # type: ignore[method-assign]
    apart = np.abs(new.poses - old.poses).reshape(len(truth), -1).max(axis=1) > 1e-9
    first = int(np.argmax(apart)) if apart.any() else -1
    print(f"{scene} {noise}: poses part at epoch {first}; ATE xy (origin) with the pair "
          f"rule {ate(new.poses, truth, 'origin', xy_only=True)['rmse']:.4f} m, with any two "
          f"planes {ate(old.poses, truth, 'origin', xy_only=True)['rmse']:.4f} m")  # fmt: skip
    yaw = [step_yaw_errors(r.poses, truth) for r in (new, old)]
    k = 1
    while k < len(truth):
        if max(abs(y[k]) for y in yaw) < 0.5:
            k += 1
            continue
        end = k
        while end + 1 < len(truth) and max(abs(y[end + 1]) for y in yaw) >= 0.2:
            end += 1
        sums = [float(y[k : end + 1].sum()) for y in yaw]
        if max(abs(v) for v in sums) > 1.0:
            states = [" ".join(s[:3] for s in r.statuses[k : end + 1]) for r in (new, old)]
            print(f"  epochs {k}-{end}: yaw error {sums[0]:+.2f} / {sums[1]:+.2f} deg "
                  f"(pair rule / any two); statuses {states[0]} / {states[1]}")  # fmt: skip
        k = end + 1
    print(f"  whole lap: {yaw[0].sum():+.2f} / {yaw[1].sum():+.2f} deg")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=list(SCENES))
    parser.add_argument("--noise", nargs="+", default=["0.02"])
    parser.add_argument(
        "--set", nargs="*", action="extend", default=[], help="config overrides key=value"
    )
    parser.add_argument("--why", action="store_true", help="the rule that drops each plane")
    parser.add_argument("--part", action="store_true", help="GAPS5's reference rule, parted")
    args = parser.parse_args()
    config = config_with(args.set)
    for scene in args.scenes:
        for noise in args.noise:
            if args.part:
                parting(scene, noise, config)
            report(scene, noise, config, args.why)


if __name__ == "__main__":
    main()
