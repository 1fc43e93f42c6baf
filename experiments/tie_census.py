"""Census of the plane map's ties against the simulator's labels (``planemap.tie_rule``).

    uv run python experiments/tie_census.py WORLD NOISE_M EPOCHS RULE [vehicle|handheld]

Runs the default odometry on generalisation world ``WORLD`` (as ``planodom experiment
generalisation`` does, ``planemap.tie_rule`` set to ``RULE``) and prints one JSON line:
the run's rotation / xy rms per epoch and ATE (the experiment's metrics) and, per
committed epoch and inlier association (scan plane -> landmark), with every point's true
surface (``Plane.truth_id``; surfaces of one plane, a wall in segments, counted as one)
and each landmark's surface (that of the scan plane that started it):

- ``wrong``: the landmark's surface is not the plane's;
- ``dup``: two or more gated landmarks of the plane's surface (duplicates);
- ``weak``: one of them has a tenth of the chosen landmark's offset variance at the plane
  (a much better informed landmark of the same surface passed over);
- ``cf_differ``: the ``distance`` and ``likelihood`` rules would choose differently at the
  registration's final pose (``cf_dist_weak``, ``cf_dist_wrong``: and ``distance``'s
  choice is weak / wrong).

The gates are recomputed at the registration's final pose with the odometry's current
deviations (the hypotheses' own gates are not), so the counts are those of the final
associations. Diagnostic only: it wraps the odometry's map methods.
"""

from __future__ import annotations

import hashlib
import json
import sys

import numpy as np

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import declared_sweep, world_for
from planodom.geometry import invert_transform
from planodom.metrics import ate, per_epoch_errors, relative_motions
from planodom.odometry import run_odometry
from planodom.odometry.planemap import landmarks as lmk
from planodom.odometry.planemap import odometry as odm
from planodom.odometry.planemap import register as reg
from planodom.simulation.random_world import simulate_world, world_fields


def _surface_groups(world) -> dict[int, int]:
    """Surface id -> group of the surfaces with the same plane (normal and offset)."""
    sc = world.scene
    key = np.round(np.c_[sc.normals, sc.offsets], 6)
    _, grp = np.unique(key, axis=0, return_inverse=True)
    return {int(i): int(g) for i, g in zip(np.asarray(sc.ids), grp.ravel(), strict=True)}


def main(argv: list[str]) -> None:
    world_i, noise, epochs, rule = int(argv[0]), float(argv[1]), int(argv[2]), argv[3]
    motion = argv[4] if len(argv) > 4 else "vehicle"
    world = world_for(world_i, motion)
    groups = _surface_groups(world)

    def group(ids) -> np.ndarray:
        return np.array([groups.get(int(x), -2 - int(x)) if x >= 0 else -1 for x in ids])

    stats = dict.fromkeys(
        ("assoc", "wrong", "dup", "weak", "weak_pts", "epochs_weak", "cf_differ",
         "cf_dist_weak", "cf_dist_wrong"), 0)  # fmt: skip
    current: dict[str, np.ndarray] = {}
    add, keep = lmk.PlaneMap.add, lmk.PlaneMap.keep

    def add_labelled(self, m, normals, frame, index):
        old = getattr(self, "truth", np.zeros(0, dtype=np.int64))
        new = current["truth"][np.asarray(index, dtype=np.int64)]
        self.truth = np.r_[old, new].astype(np.int64)
        add(self, m, normals, frame, index)

    def keep_labelled(self, sel):
        self.truth = getattr(self, "truth", np.full(len(self), -1))[sel]
        keep(self, sel)

    estimate, commit = odm.PlaneMapOdometry.estimate, odm.PlaneMapOdometry.commit

    def estimate_labelled(self, planes, *args, **kwargs):
        est = estimate(self, planes, *args, **kwargs)
        object.__setattr__(est, "_truth", group([p.truth_id for p in planes]))
        return est

    def commit_counted(self, est):
        truth = est._truth
        current["truth"] = truth
        M, r = self.map, est.reg
        if r is not None and est.cur is not None and len(M) and len(r.planes):
            s_r, s_t = self.sigmas()
            _count(M, est, truth, s_r, s_t, stats)
        commit(self, est)

    # instrumentation of this process only: the map and the odometry carry the labels
    lmk.PlaneMap.add, lmk.PlaneMap.keep = add_labelled, keep_labelled  # type: ignore[method-assign]
    odm.PlaneMapOdometry.estimate = estimate_labelled  # type: ignore[method-assign]
    odm.PlaneMapOdometry.commit = commit_counted  # type: ignore[method-assign]

    full = simulate_world(world, noise, n_epochs=epochs, all_fields=True)
    cfg = declared_sweep(world, PlanodomConfig()).updated({"planemap.tie_rule": rule})
    run = run_odometry(world_fields(world, full), cfg)
    gt = invert_transform(full.poses[0])[None] @ full.poses
    err = per_epoch_errors(relative_motions(run.poses), relative_motions(gt))
    rot = np.degrees(np.sqrt(err["roll"] ** 2 + err["pitch"] ** 2 + err["yaw"] ** 2))
    xy = np.hypot(err["x"], err["y"])
    digest = hashlib.sha1(np.ascontiguousarray(run.poses).tobytes()).hexdigest()[:12]
    out = dict(world=world_i, noise=noise, rule=rule, motion=motion,
               rot_rms_deg=float(np.sqrt(np.mean(rot**2))),
               xy_rms_m=float(np.sqrt(np.mean(xy**2))),
               ate_xy_m=ate(run.poses, gt, align="origin", xy_only=True)["rmse"],
               statuses={s: run.statuses.count(s) for s in sorted(set(run.statuses))},
               **stats, poses_sha1=digest)  # fmt: skip
    print(json.dumps(out))


def _count(M, est, truth, s_r: float, s_t: float, stats: dict) -> None:
    """Add one epoch's ties to ``stats`` (module docstring)."""
    r, cur = est.reg, est.cur
    c = reg.candidates(M, r.T, cur, s_r, s_t, cur.bias)
    cost_d, cost_l = reg.tie_cost(c, "distance"), reg.tie_cost(c, "likelihood")
    cw = cur.m.c @ r.T[:3, :3].T + r.T[:3, 3]
    weak_epoch = False
    for lm, j, w in zip(r.landmarks, r.planes, r.weights, strict=True):
        pt = truth[est.used[j]]
        if w <= 0.5 or pt == -1:
            continue
        stats["assoc"] += 1
        stats["wrong"] += int(M.truth[lm] != pt)
        same = np.flatnonzero(c.ok[j] & (M.truth == pt))
        var_same = M.var_at(same, np.repeat(cw[j][None], len(same), 0))

        def weak(k: int, same=same, var_same=var_same, j=j) -> bool:
            return len(same) >= 2 and var_same.min() * 10 < M.var_at(np.array([k]), cw[j][None])[0]

        if len(same) >= 2:
            stats["dup"] += 1
            if weak(int(lm)):
                stats["weak"] += 1
                stats["weak_pts"] += int(cur.m.N[j])
                weak_epoch = True
        bd, bl = int(np.argmin(cost_d[j])), int(np.argmin(cost_l[j]))
        if np.isfinite(cost_d[j, bd]) and bd != bl:
            stats["cf_differ"] += 1
            stats["cf_dist_wrong"] += int(M.truth[bd] != pt)
            stats["cf_dist_weak"] += int(M.truth[bd] == pt and weak(bd))
    stats["epochs_weak"] += int(weak_epoch)


if __name__ == "__main__":
    main(sys.argv[1:])
