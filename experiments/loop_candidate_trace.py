"""Where a lap's loop candidates are lost: every stage of the loop-candidate search traced
against the truth (a diagnostic, issue 14, W32D).

One lap of a procedural world (the batch's odometry, as ``wrong_ties.py``: ``--odometry
FILE`` caches it), the batch with loops once, :class:`CandidateLoopBuilder`'s stages
observed in-process (its decisions unchanged: each wrapped method's own result is
returned). Per epoch k at which the truth has a revisit (an old epoch e at least
``loop_min_gap_epochs`` before, within ``loop_candidate_radius_m`` of k's true position,
the true route between them at least ``REVISIT_RATIO`` times their distance plus the
radius), and per old epoch the search tried:

- the search: the true revisits, the candidates found, and for the truly nearest old epoch
  its predicted distance from k against the search's reach (``loop_candidate_radius_m``
  plus the translation bound) and the prediction's error (the predicted ``T_e_k`` against
  the true one: horizontal m, yaw deg) against the LDA bounds;
- per tried old epoch: the stage that refused it (``status`` of the relative pose,
  ``inliers``, ``parallel``, ``overlap``, ``alias``: the ambiguity test, ``map``: disagrees
  with the map's tracked correction, ``implausible``, ``unconfirmed``: no verified loop
  pose within ``loop_candidate_confirm_epochs`` before, ``disagrees``: with that one), or
  ``added``; and the relative pose's error against the truth (m, deg).

The first line (JSON) holds the stage counts and the lap's loop factors; then one line
per traced epoch (``--from K``: from epoch K on; default: every epoch with a true revisit).

    uv run python experiments/loop_candidate_trace.py 32 0.02 [JSON] --odometry FILE [--from K]
    uv run python experiments/loop_candidate_trace.py 284 0.02 [JSON] [--from K] --lap-cache DIR

``--lap-cache DIR`` (last): the default odometry from ``nees_gauge.load``'s cache instead.
"""

from __future__ import annotations

import json
import sys
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from wrong_ties import lap_odometry  # noqa: E402

import planodom.smoothing.batch as batch  # noqa: E402
from planodom.config import PlanodomConfig  # noqa: E402
from planodom.experiments.generalisation import world_for  # noqa: E402
from planodom.experiments.loops import coplanar  # noqa: E402
from planodom.geometry import invert_transform, pose5_from_transform  # noqa: E402
from planodom.metrics import ate  # noqa: E402
from planodom.odometry import Status, estimate_relative_pose  # noqa: E402
from planodom.smoothing.loop_candidates import REVISIT_RATIO, CandidateLoopBuilder  # noqa: E402
from planodom.smoothing.match_fit import _extent, non_parallel  # noqa: E402


def pose_error(T_est: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    """(horizontal m, |yaw| deg) of ``T_true^-1 T_est``."""
    v = pose5_from_transform(invert_transform(T_true) @ T_est)
    return float(np.hypot(v[3], v[4])), float(abs(np.degrees(v[2])))


def traced_builder(gt: np.ndarray, log: dict) -> type[CandidateLoopBuilder]:
    """A :class:`CandidateLoopBuilder` whose loop-candidate stages are noted in ``log``
    ((k, e) -> record; k -> the epoch's search); the decisions are the wrapped methods'."""

    class Traced(CandidateLoopBuilder):
        def old_epoch_candidates(self, k: int) -> list[int]:
            out = super().old_epoch_candidates(k)
            c = self.config
            last = k - c.loop_min_gap_epochs
            if last < 0:
                return out
            steps = np.linalg.norm(np.diff(gt[: k + 1, :2, 3], axis=0), axis=1)
            travelled_true = np.r_[0.0, np.cumsum(steps)]
            dist = np.linalg.norm(gt[: last + 1, :2, 3] - gt[k, :2, 3], axis=1)
            driven = travelled_true[k] - travelled_true[: last + 1]
            true = np.flatnonzero(
                (dist <= c.loop_candidate_radius_m)
                & (driven >= REVISIT_RATIO * (dist + c.loop_candidate_radius_m))
            )
            row = {"true": len(true), "found": out}
            if len(true):
                e = int(true[np.argmin(dist[true])])
                translation, rotation = self._bounds(k, np.array([e]))
                pred = self._predicted(k)
                prior = invert_transform(self.poses[e]) @ pred
                err_m, err_deg = pose_error(prior, invert_transform(gt[e]) @ gt[k])
                _, _, positions = self._history()
                chained = invert_transform(self.poses[e]) @ self.poses[k]
                chained_m, _ = pose_error(chained, invert_transform(gt[e]) @ gt[k])
                reference, self._reference = self._reference, None
                untracked = float(self._bounds(k, np.array([e]))[0][0])
                self._reference = reference
                row |= {
                    "reference": reference, "chained_err_m": chained_m, "untracked_m": untracked,
                    "nearest": e, "true_dist": float(dist[e]),
                    "pred_dist": float(np.linalg.norm(positions[e] - pred[:2, 3])),
                    "reach": float(c.loop_candidate_radius_m + translation[0]),
                    "prior_err_m": err_m, "prior_err_deg": err_deg,
                    "bound_m": float(translation[0]), "bound_deg": float(rotation[0]),
                }  # fmt: skip
            log[k] = row
            return out

        def match_old_epoch(self, k: int, e: int):  # noqa: ANN201
            rec = log.setdefault((k, e), {})
            rec["stage"] = self._stage(k, e, rec)
            out = super().match_old_epoch(k, e)
            if (out is None) != (rec["stage"] != "verified"):
                raise AssertionError(f"trace disagrees with the builder at {k}-{e}: {rec}")
            return out

        def _stage(self, k: int, e: int, rec: dict) -> str:
            """match_old_epoch's own checks, in order, naming the first that refuses."""
            c = self.config
            prior = invert_transform(self.poses[e]) @ self._predicted(k)
            translation, rotation = self._bounds(k, np.array([e]))
            cfg = self._bounded(float(translation[0]), float(rotation[0]))
            rel = estimate_relative_pose(self.planes[e], self.planes[k], cfg, prior=prior)
            T_true = invert_transform(gt[e]) @ gt[k]
            rec["prior_err"] = pose_error(prior, T_true)
            rec["bound"] = (float(translation[0]), float(rotation[0]))
            rec["err"] = pose_error(np.asarray(rel.T_prev_curr, float), T_true)
            pairs = np.asarray(rel.associations, dtype=int).reshape(-1, 2)
            rec["inliers"] = len(pairs)
            rec["status"] = str(rel.status)
            if rel.status is not Status.OK:
                return f"status {rel.status}"
            if len(pairs) < c.loop_candidate_min_inliers:
                return "inliers"
            if not non_parallel(np.stack([self.planes[k][i].normal for i in pairs[:, 1]])):
                return "parallel"
            T_k_e = invert_transform(np.asarray(rel.T_prev_curr, dtype=float))
            for i, j in pairs:
                c_old, r_old = _extent(self.planes[e][i], T_k_e)
                c_cur, r_cur = _extent(self.planes[k][j], np.eye(4))
                if np.linalg.norm(c_old - c_cur) - r_old - r_cur > c.loop_candidate_overlap_m:
                    return "overlap"
            test = c.loop_refuse_ambiguous not in ("off", "run")
            test = test or c.loop_candidate_aliases != "off"
            if test and self._ambiguous(e, k, rel, pairs, prior, translation[0]):
                return "alias"
            return "verified"

        def _agrees_with_map(self, rel) -> bool:  # noqa: ANN001
            ok = super()._agrees_with_map(rel)
            log[(rel.curr, rel.prev)]["map"] = ok
            return ok

        def _plausible(self, rel) -> bool:  # noqa: ANN001
            ok = super()._plausible(rel)
            log[(rel.curr, rel.prev)]["plausible"] = ok
            rec = log[(rel.curr, rel.prev)]
            last = self._last_verified
            rec["previous"] = None if last is None else (last.curr, last.prev)
            return ok

        def _agrees(self, first, second) -> bool:  # noqa: ANN001
            ok = super()._agrees(first, second)
            log[(second.curr, second.prev)]["agrees"] = ok
            return ok

        def corrections_agree(self, a, b) -> bool:  # noqa: ANN001
            ok = super().corrections_agree(a, b)
            cov = self._candidate_drift([(a.epoch, b.epoch), (a.old, b.old)])
            cov = cov + a.covariance + b.covariance
            T_b = self.poses[b.epoch]
            v = pose5_from_transform(invert_transform(a.W @ T_b) @ b.W @ T_b)[2:]
            chi = float(v @ np.linalg.solve(cov, v))
            log.setdefault("agree", []).append(
                (a.epoch, a.old, b.epoch, b.old, ok, chi, float(np.sqrt(cov[1, 1])), v)
            )
            return ok

        def _add_loop_factor(self, update, rel) -> None:  # noqa: ANN001
            super()._add_loop_factor(update, rel)
            log.setdefault((rel.curr, rel.prev), {})["added"] = True

    return Traced


def final_stage(rec: dict) -> str:
    """The stage that ended a tried (k, e)."""
    if rec.get("stage") != "verified":
        return rec.get("stage", "?")
    if not rec.get("map", True):
        return "map"
    if "plausible" in rec and not rec["plausible"]:
        return "implausible"
    if rec.get("added"):
        return "added"
    if "agrees" in rec:
        return "disagrees" if not rec["agrees"] else "added"
    return "unconfirmed"


def main(argv: list[str]) -> None:
    cache = start = None
    for flag in ("--odometry", "--from"):
        if flag in argv:
            at = argv.index(flag)
            value, argv = argv[at + 1], argv[:at] + argv[at + 2 :]
            cache, start = (Path(value), start) if flag == "--odometry" else (cache, int(value))
    index, noise = int(argv[0]), float(argv[1])
    changes = json.loads(argv[2]) if len(argv) > 2 and argv[2] != "--lap-cache" else {}
    cfg = PlanodomConfig().updated(changes)
    if "--lap-cache" in argv:  # nees_gauge's cache of the default odometry (DIR)
        import nees_gauge

        _, full, _, odo, relatives = nees_gauge.load(index, noise, Path(argv[-1]))
        planes, gt = odo.planes, invert_transform(full.poses[0])[None] @ full.poses
        argv = argv[: argv.index("--lap-cache")]
    else:
        planes, relatives, gt = lap_odometry(index, noise, cfg, cache)
    log: dict = {}
    batch.CandidateLoopBuilder = traced_builder(gt, log)  # type: ignore[misc]  # this process
    run_cfg = cfg.updated(
        {"smoothing.loop_closure": True, "smoothing.compute_covariances": False, **changes}
    )
    res = batch.smooth_batch(planes, relatives, run_cfg)
    tried = {key: rec for key, rec in log.items() if isinstance(key, tuple)}
    searched = {k: row for k, row in log.items() if isinstance(k, int)}
    groups: dict[int, list] = {}
    for f in res.loop_factors:
        groups.setdefault(f.group, []).append(f)
    for g, fs in sorted(groups.items()):
        err = [float(np.linalg.norm(f.truth_error(gt)[3:])) for f in fs]
        print(
            f"hypothesis {g}: {len(fs)} factors {fs[0].epoch}-{fs[-1].epoch} against "
            f"{sorted({f.old for f in fs})}, {min(err):.2f}-{max(err):.2f} m off the truth, "
            f"removed {sum(f.removed for f in fs)}, chi2 at the gate {fs[0].chi2:.1f}, "
            f"increase {fs[0].increase:.3g}"
        )
    for a_k, a_o, b_k, b_o, ok, chi, sd, v in log.get("agree", []):  # the clique's tests
        print(
            f"agreement {a_k}-{a_o} with {b_k}-{b_o}: {'agree' if ok else 'DISAGREE'}, chi2 "
            f"{chi:.1f}, drift sd {sd:.2f} m, difference yaw {np.degrees(v[0]):.2f} deg "
            f"xy {np.hypot(v[1], v[2]):.2f} m"
        )
    stages = Counter(final_stage(r) for r in tried.values())
    revisits = [k for k, row in searched.items() if row["true"]]
    head = {
        "world": index, "noise_m": noise, "changes": changes,
        "epochs_searched": len(searched), "epochs_with_true_revisit": len(revisits),
        "epochs_with_candidates": sum(bool(r["found"]) for r in searched.values()),
        "true_revisit_and_candidates": sum(bool(searched[k]["found"]) for k in revisits),
        "tried": len(tried), "stages": dict(stages),
        "ate_m": ate(res.poses, gt, xy_only=True)["rmse"],
        "loop_end_m": float(np.linalg.norm(res.poses[-1][:2, 3] - gt[-1][:2, 3])),
        "loop_factors": len(res.loop_factors),
        "loop_factors_removed": sum(f.removed for f in res.loop_factors),
    }  # fmt: skip
    print(json.dumps(head))
    world = world_for(index)
    same = coplanar(world.scene)
    normals = {s.id: np.asarray(s.normal, float) for s in world.scene.surfaces}
    normals[-1] = np.zeros(3)
    reids: dict[int, list] = {}
    for r in res.reidentifications:
        reids.setdefault(r.epoch, []).append(r)
    for m in res.loop_matches if start is not None else ():  # the map's matches
        if m.epoch < (start or 0):
            continue
        k, placed = m.epoch, m.T_world_pred @ m.T_pred_curr
        err = placed[:2, 3] - gt[k][:2, 3]  # world frame = the truth's (both from epoch 0)
        ties = [
            f"{r.truth_plane}->{r.truth_landmark} "
            f"{'ok' if same(r.truth_plane, r.truth_landmark) else 'WRONG'}"
            + (
                f" n.err {normals[r.truth_plane][:2] @ err:+.2f}"
                if r.truth_plane in normals
                else ""
            )
            for r in reids.get(k, [])
        ]
        sd = float(np.sqrt(m.drift[1, 1])) if m.drift.any() else float("nan")
        print(
            f"map match {k}: {'full' if m.full else 'rotation'} {m.verdict}, seen {m.seen} "
            f"spanning {m.spanning}, "
            f"mahalanobis {m.mahalanobis:.2f}, drift sd {sd:.2f} m, predicted "
            f"{pose_error(m.T_world_pred, gt[k])[0]:.2f} m, matched "
            f"{pose_error(placed, gt[k])[0]:.2f} m off the truth, {len(m.ties)} ties "
            f"{ties}"
        )
    for k in sorted(searched):
        row = searched[k]
        if (start is None and not row["true"]) or (start is not None and k < start):
            continue
        line = f"epoch {k}: true revisits {row['true']}"
        if row["true"]:
            line += (
                f", nearest {row['nearest']} {row['true_dist']:.2f} m (predicted "
                f"{row['pred_dist']:.2f} m, reach {row['reach']:.2f} m; prior off "
                f"{row['prior_err_m']:.2f} m {row['prior_err_deg']:.1f} deg, bounds "
                f"{row['bound_m']:.2f} m {row['bound_deg']:.1f} deg; map's reference "
                f"{row['reference']}; chained guess off {row['chained_err_m']:.2f} m, bound "
                f"without the reference {row['untracked_m']:.2f} m)"
            )
        parts = []
        for e in row["found"]:
            rec = tried.get((k, e))
            if rec is None:
                parts.append(f"{e} not tried")
                continue
            true_d = float(np.linalg.norm(gt[e][:2, 3] - gt[k][:2, 3]))
            parts.append(
                f"{e} ({true_d:.1f} m) {final_stage(rec)} [{rec.get('status')}, "
                f"{rec.get('inliers')} inl, off {rec['err'][0]:.2f} m {rec['err'][1]:.1f} deg]"
            )
        print(line + ("; tried: " + "; ".join(parts) if parts else "; no candidate"))


if __name__ == "__main__":
    main(sys.argv[1:])
