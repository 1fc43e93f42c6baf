"""What the 2D rig loses against the oracle, ingredient by ingredient (issue 11).

The oracle (:mod:`planodom.oracle`) differs from planodom in four ingredients: the
deskewing (the true motion removed), the segmentation (every labelled point of a surface
is one plane), the association (the labels) and the solve (weighted least squares of the
points' distances to the other epoch's planes over all common planes, both ways). Per
world and range noise this runs planodom and variants with oracle ingredients swapped in:

- ``planodom``: planodom as it is (default configuration).
- ``true-deskew``: every scan deskewed with the true motion (:func:`oracle.deskewed_points`)
  and given to planodom as deskewed already, always kept (the streaming deskewing is never
  tried: ``prefer_streaming`` forced off); planodom's extraction, association and solve.
- ``curve-deskew``: every scan deskewed along the cubic curve through the *true* epoch
  poses (:func:`planodom.odometry.interpolate.midpoint_nodes`, as
  ``odometry.deskew_passes`` deskews through its own poses) and given to planodom as
  deskewed already (as ``true-deskew``): what a deskewing by the poses of the epochs on
  both sides reaches when those poses are exact (``--runs``; not run by default).
- ``<run>+osolve``: the planes and strict associations planodom committed for every epoch
  (recorded at commit: the epoch's planes and the reference planes they were estimated
  against), the relative pose solved by the oracle's solve over all associated pairs
  (each plane's inlier moments as its weight; what is measured judged on the surfaces'
  true normals, from the planes' ``truth_id``), chained as the oracle chains.
- ``<run>+labels+osolve``: the same planes grouped by their true surface (``truth_id``,
  fragments of one surface merged into one plane by their moments), associated by the
  label, the oracle's solve.
- ``oracle-pdeskew``: the oracle (labels, all labelled points, its solve) on the points
  deskewed with the twist planodom deskewed each epoch with (zero where it did not
  deskew: the time windows; the first epoch with the second's twist).
- ``oracle``.

``<run>`` is ``planodom``, ``true-deskew`` or ``curve-deskew``. Per variant: per-epoch
rotation and xy rms, ATE (xy, origin-aligned) as in ``planodom experiment
generalisation``, and their ratios to the oracle's. Writes a CSV (one row per world,
noise and variant).

    uv run python experiments/rig2d_ingredients.py --worlds 160,168,172,178 \
        --noise 0.006 0.02 --epochs 150 -o OUT.csv
    uv run python experiments/rig2d_ingredients.py --worlds 340,346,352,356 \
        --noise 0.006 0.02 --epochs 150 --runs curve-deskew -o CURVE.csv
"""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace

import numpy as np
import yaml

import planodom.odometry.odometry as odometry_module
from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import world_for
from planodom.extraction.deskew import deskew_points
from planodom.geometry import Plane, invert_transform, orthonormalised, se3_exp, se3_log
from planodom.metrics import ate, per_epoch_errors, relative_motions
from planodom.odometry.deskewed_epochs import Deskewed
from planodom.odometry.interpolate import deskew_with_poses, midpoint_nodes
from planodom.odometry.odometry import PlaneOdometry
from planodom.odometry.run import _streaming_pass, with_motion_bounds
from planodom.oracle import (
    SurfaceMoments,
    deskewed_points,
    relative_pose,
    run_oracle,
)
from planodom.results import write_rows
from planodom.rig import Rig
from planodom.scan import Scan
from planodom.simulation.random_world import simulate_world, world_fields

#: Solves that failed (diverged), what they were given: counted per variant.
FAILURES: list[str] = []


@dataclass
class Committed:
    """What planodom committed for one epoch: its planes, the reference epoch's planes
    they were estimated against, the relative pose (None: the first epoch) and the twist
    the scan was deskewed with (None: not deskewed)."""

    planes: list[Plane]
    reference_planes: list[Plane]
    relative: object
    twist: np.ndarray | None


@contextlib.contextmanager
def recording(log: list[Committed], force_given: bool = False) -> Iterator[None]:
    """Record every epoch PlaneOdometry commits in ``log``; with ``force_given`` an epoch
    given deskewed already is always kept (``prefer_streaming`` off)."""
    commit, first, prefer = (
        PlaneOdometry._commit,
        PlaneOdometry._commit_first,
        odometry_module.prefer_streaming,
    )

    def _commit(self, epoch, best, t):
        log.append(Committed(best.planes, best.reference_planes, best.relative, epoch.twist))
        return commit(self, epoch, best, t)

    def _commit_first(self, epoch, t):
        log.append(Committed(epoch.planes, [], None, epoch.twist))
        return first(self, epoch, t)

    PlaneOdometry._commit = _commit  # type: ignore[method-assign]
    PlaneOdometry._commit_first = _commit_first  # type: ignore[method-assign]
    if force_given:
        odometry_module.prefer_streaming = lambda given, previous_planes: False
    try:
        yield
    finally:
        PlaneOdometry._commit = commit  # type: ignore[method-assign]
        PlaneOdometry._commit_first = first  # type: ignore[method-assign]
        odometry_module.prefer_streaming = prefer


def plane_moments(
    planes: Sequence[Plane], ids: np.ndarray, true_normals: np.ndarray, merge: bool
) -> SurfaceMoments:
    """The oracle's moments of ``planes`` with ``ids`` (K,); with ``merge`` the planes of
    one id merged (summed moments, TLS plane; a single plane keeps its own fit)."""
    rows = []
    for i in dict.fromkeys(ids.tolist()) if merge else range(len(planes)):
        members = np.flatnonzero(ids == i) if merge else np.array([i])
        ps = [planes[int(j)] for j in members]
        supports = [p.support for p in ps]
        if any(s is None or s.scatter is None for s in supports):
            continue
        counts = np.array([s.n_points for s in supports if s is not None], dtype=np.float64)
        cents = np.array([s.centroid for s in supports if s is not None])
        n = counts.sum()
        c = counts @ cents / n
        scatters = [s.scatter for s in supports if s is not None and s.scatter is not None]
        S = np.sum(scatters, axis=0) + np.einsum("k,ki,kj->ij", counts, cents - c, cents - c)
        if len(ps) == 1:
            normal, offset = ps[0].normal, ps[0].offset
        else:
            normal = np.linalg.eigh(S)[1][:, 0]
            offset = float(-normal @ c)
        key = i if merge else int(ids[i])
        rows.append((key, n, c, S, normal, offset, true_normals[members[0]]))
    if not rows:
        z = np.zeros((0, 3))
        return SurfaceMoments(np.zeros(0, int), np.zeros(0), z, np.zeros((0, 3, 3)), z,
                              np.zeros(0), z)  # fmt: skip
    cols = [np.array(c) for c in zip(*rows, strict=True)]
    return SurfaceMoments(*cols)


def true_normals(planes: Sequence[Plane], scene, R_world_base: np.ndarray) -> np.ndarray:
    """(K, 3) the true surface normals of ``planes`` in the base frame (the fitted
    normal where the plane has no ``truth_id``)."""
    out = []
    for p in planes:
        if p.truth_id >= 0:
            out.append(scene.by_id(p.truth_id).normal @ R_world_base)
        else:
            out.append(p.normal)
    return np.array(out).reshape(-1, 3)


def oracle_solve(
    log: Sequence[Committed],
    times: np.ndarray,
    T_world_base: np.ndarray,
    scene,
    labels: bool,
    bounds: tuple[float, float],
) -> tuple[np.ndarray, list[str]]:
    """Poses (E, 4, 4) and statuses of the oracle's solve over planodom's committed planes
    (module docstring): associated by planodom (``labels`` False) or by ``truth_id``;
    ``T_world_base`` (E, 4, 4) the true poses in the scene's frame (the true normals)."""
    poses, statuses, steps = [np.eye(4)], ["first"], [np.eye(4)]
    velocity = np.zeros(6)
    for k in range(1, len(log)):
        c = log[k]
        rel = c.relative
        prev = rel.prev  # type: ignore[attr-defined]
        dt = float(times[k] - times[k - 1])
        T_prev_last = np.eye(4)  # through the steps: inverting chained poses amplifies drift
        for st in steps[prev + 1 : k]:
            T_prev_last = T_prev_last @ st
        init = T_prev_last @ se3_exp(velocity * dt)
        Rp, Rc = T_world_base[prev][:3, :3], T_world_base[k][:3, :3]
        refs, curs = c.reference_planes, c.planes
        if labels:
            ids_p = np.array([p.truth_id for p in refs], int)
            ids_c = np.array([p.truth_id for p in curs], int)
            keep_p, keep_c = np.flatnonzero(ids_p >= 0), np.flatnonzero(ids_c >= 0)
            mp = plane_moments(
                [refs[i] for i in keep_p],
                ids_p[keep_p],
                true_normals([refs[i] for i in keep_p], scene, Rp),
                True,
            )
            mc = plane_moments(
                [curs[i] for i in keep_c],
                ids_c[keep_c],
                true_normals([curs[i] for i in keep_c], scene, Rc),
                True,
            )
        else:
            assoc = np.asarray(rel.associations, dtype=np.int64).reshape(-1, 2)  # type: ignore[attr-defined]
            ids = np.arange(len(assoc))
            pp = [refs[i] for i in assoc[:, 0]]
            cc = [curs[i] for i in assoc[:, 1]]
            mp = plane_moments(pp, ids, true_normals(pp, scene, Rp), False)
            mc = plane_moments(cc, ids, true_normals(cc, scene, Rc), False)
        step, status = solved_step(mp, mc, init, T_prev_last, bounds)
        if status != "unresolved" and dt > 0:
            velocity = se3_log(step) / dt
        step = orthonormalised(step)
        steps.append(step)
        poses.append(orthonormalised(poses[k - 1] @ step))
        statuses.append(status)
    return np.array(poses), statuses


def solved_step(
    mp: SurfaceMoments,
    mc: SurfaceMoments,
    init: np.ndarray,
    T_prev_last: np.ndarray,
    bounds: tuple[float, float],
) -> tuple[np.ndarray, str]:
    """The oracle's step ``T_{k-1}_k`` (4, 4) and status from the moments; a solve that
    fails or lands beyond the association's bounds (rad, m) from ``init`` (a wrong
    association planodom made: the oracle has none) is unresolved and keeps ``init``."""
    try:
        with np.errstate(all="ignore"):
            est = relative_pose(mp, mc, init)
        T, status = est.T_prev_curr, est.status
        R = T[:3, :3]
        if not (np.all(np.isfinite(T)) and np.allclose(R.T @ R, np.eye(3), atol=1e-3)):
            raise ValueError("diverged")
        T = orthonormalised(T)  # the Gauss-Newton products drift from a rotation (1e-5)
        off = se3_log(invert_transform(init) @ T)
    except (np.linalg.LinAlgError, ValueError) as exc:
        FAILURES.append(f"{exc}: {len(mp)} / {len(mc)} planes, points {mc.count.tolist()}")
        T, status, off = init, "unresolved", np.full(6, np.inf)
    if not (np.linalg.norm(off[:3]) <= bounds[0] and np.linalg.norm(off[3:]) <= bounds[1]):
        T, status = init, "unresolved"
    return invert_transform(T_prev_last) @ T, status


def oracle_pdeskew(run, log: Sequence[Committed], scene) -> tuple[np.ndarray, list[str]]:
    """The oracle on the points deskewed with planodom's twists (module docstring)."""
    twists = [c.twist for c in log]
    if twists[0] is None and len(twists) > 1:
        twists[0] = twists[1]
    scans = []
    for scan, twist in zip(run.scans, twists, strict=True):
        pts = scan.points if twist is None else deskew_points(scan.points, scan.t, twist)
        scans.append(Scan(pts, scan.ring, np.zeros(len(pts)), scan.label))
    orc = run_oracle(scans, run.times, run.trajectory, scene)
    return orc.poses, orc.statuses


def metrics(poses: np.ndarray, gt: np.ndarray) -> dict[str, float]:
    """Per-epoch rotation and xy rms, ATE (as ``generalisation._metrics``)."""
    err = per_epoch_errors(relative_motions(poses), relative_motions(gt))
    rot = np.degrees(np.sqrt(err["roll"] ** 2 + err["pitch"] ** 2 + err["yaw"] ** 2))
    xy = np.hypot(err["x"], err["y"])
    return {
        "rot_rms_deg": float(np.sqrt(np.mean(rot**2))),
        "xy_rms_m": float(np.sqrt(np.mean(xy**2))),
        "ate_xy_m": float(ate(poses, gt, align="origin", xy_only=True)["rmse"]),
    }


def run_world(
    index: int,
    noise: float,
    n_epochs: int,
    config: PlanodomConfig,
    quick: bool = False,
    runs: Sequence[str] = ("planodom", "true-deskew"),
) -> list[dict]:
    """Every variant on world ``index`` at ``noise`` (m) whose ``<run>`` is in ``runs``
    (``oracle-pdeskew`` with ``planodom``); with ``quick`` only planodom and the
    oracle."""
    world = world_for(index)
    full = simulate_world(world, noise, n_epochs=n_epochs, all_fields=True)
    run = world_fields(world, full)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    out: dict[str, tuple[np.ndarray, list[str]]] = {}
    orc = run_oracle(full.scans, full.times, world.trajectory, world.scene)
    out["oracle"] = orc.poses, orc.statuses
    rig = getattr(run, "rig", None) or Rig()
    config = with_motion_bounds(config, rig.motion_bounds)  # as run_odometry
    logs: dict[str, list[Committed]] = {}
    a = config.association
    bounds = (float(np.radians(a.max_rotation_deg)), float(a.max_translation_m))
    for name in ("planodom",) if quick else runs:
        log: list[Committed] = []
        if name == "planodom":
            source: Sequence = run.scans
        elif name == "curve-deskew":
            node_times, node_poses = midpoint_nodes(full.times, full.poses)
            source = [
                Deskewed(s, replace(s, points=deskew_with_poses(f, node_times, node_poses,
                                                                float(t)).points))
                for s, f, t in zip(run.scans, full.scans, full.times, strict=True)
            ]  # fmt: skip
        else:
            source = [
                Deskewed(s, replace(s, points=deskewed_points(f, world.trajectory, float(t))))
                for s, f, t in zip(run.scans, full.scans, full.times, strict=True)
            ]
        with recording(log, force_given=name != "planodom"):
            odo = _streaming_pass(source, config, rig, full.times, None, None)
        assert len(log) == len(odo.poses)
        out[name] = odo.poses, odo.statuses
        logs[name] = log
        for labels in () if quick else (False, True):
            key = f"{name}+labels+osolve" if labels else f"{name}+osolve"
            FAILURES.clear()
            out[key] = oracle_solve(log, full.times, full.poses, world.scene, labels, bounds)
            if FAILURES:
                print(key, len(FAILURES), "solves failed, e.g.", FAILURES[0], flush=True)
    if not quick and "planodom" in logs:
        out["oracle-pdeskew"] = oracle_pdeskew(full, logs["planodom"], world.scene)
    rows = []
    ref = metrics(*out["oracle"][:1], gt)
    for name, (poses, statuses) in out.items():
        m = metrics(poses, gt)
        row: dict[str, object] = {"world": index, "noise_m": noise, "variant": name}
        row |= m
        row |= {f"{k}_x_oracle": m[k] / ref[k] if ref[k] > 0 else float("nan") for k in m}
        st = np.array(statuses)
        row |= {"unresolved": int((st == "unresolved").sum()),
                "degenerate": int((st == "degenerate").sum())}  # fmt: skip
        rows.append(row)
        print(index, noise, name, {k: round(float(v), 5) for k, v in m.items()},
              "x oracle", {k: round(float(row[f"{k}_x_oracle"]), 2) for k in m},  # type: ignore[arg-type]
              flush=True)  # fmt: skip
    return rows


def main(argv: Sequence[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--worlds", default="160,168,172,178")
    ap.add_argument("--noise", type=float, nargs="+", default=[0.006, 0.02])
    ap.add_argument("--epochs", type=int, default=150)
    ap.add_argument("-o", "--out", default=None, help="CSV of the rows")
    ap.add_argument(
        "--set", nargs="*", action="extend", default=[], help="config overrides KEY=VALUE (YAML)"
    )
    ap.add_argument("--quick", action="store_true", help="planodom and the oracle only")
    ap.add_argument(
        "--runs", default="planodom,true-deskew",
        help="of planodom, true-deskew, curve-deskew (each with its osolve variants)",
    )  # fmt: skip
    args = ap.parse_args(argv)
    changes = {k: yaml.safe_load(v) for k, v in (kv.split("=", 1) for kv in args.set)}
    config = PlanodomConfig().updated(changes, source="--set") if changes else PlanodomConfig()
    rows: list[dict] = []
    for w in (int(x) for x in args.worlds.split(",")):
        for noise in args.noise:
            rows += run_world(w, noise, args.epochs, config, args.quick, args.runs.split(","))
            if args.out:
                write_rows(args.out, rows)


if __name__ == "__main__":
    main()
