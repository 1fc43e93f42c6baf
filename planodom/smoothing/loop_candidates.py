"""Loop candidates in batch smoothing: 5-DoF relative poses to old epochs (issue 14).

Where the chained odometry's covariance has grown, the map re-identification
(:mod:`planodom.smoothing.loops`) may find no landmark near the predicted pose (the
prediction is metres off after an odometry failure, or the old landmarks never formed).
:class:`CandidateLoopBuilder` then compares whole epochs, at every
``loop_candidate_every_epochs``-th epoch k:

1. candidates: old epochs e at least ``loop_min_gap_epochs`` before k (with
   ``loop_candidate_old`` "translated" only those with a measured translation to or from
   a neighbour: the first epoch, extracted before any motion was known, may have planes
   centimetres off that no neighbour confirmed), revisited (the
   route between them at least ``REVISIT_RATIO`` times their distance), whose (chained)
   position lies within ``loop_candidate_radius_m`` plus the translation bound of the
   drift between them (``loop_sigmas`` standard deviations of the chained odometry, at
   most ``loop_drift_fraction`` of the distance driven, as for the map matches) of k's
   predicted position (the tracked correction applied, ``loop_verify`` "tracked"); the
   nearest ``loop_candidate_max``, each ``loop_min_gap_epochs`` apart from the others;
2. the paper's odometry (:func:`planodom.odometry.estimate_relative_pose`: LDA under the
   grown bounds around the predicted ``T_e_k``, WOCSC, strict association) between the
   planes of e and k;
3. verification by its consensus: status OK (5 DoF) and at least
   ``loop_candidate_min_inliers`` strict associations spanning non-parallel normals,
   each pair's supports (centroid and radius) within ``loop_candidate_overlap_m`` of each
   other under the relative pose (the paper's overlap: aliased walls lie elsewhere); the
   correction of the chained guess it implies must agree with the map's accepted one
   (when the re-identification has one) and with the previous verified loop pose, at
   most ``loop_candidate_confirm_epochs`` before (chi2(3) on yaw, x, y); with
   ``loop_candidate_aliases`` no tie may have a competing parallel wall in either epoch
   that the prediction cannot tell from it (:meth:`_ambiguous`);
4. the first verified one becomes a 5-DoF between factor ``X(e) - X(k)``
   (:func:`factors.pose5.pose5_factor`) with the odometry's covariance (plus both
   epochs' deskewing error with ``smoothing.deskew_noise``) and a robust
   kernel (``robust_kernel``, Cauchy when "none": a loop factor is never trusted blindly).

Before optimisation (``loop_consistency``, :func:`.loop_gate.consistent_hypotheses`) only
the largest set of pairwise agreeing hypotheses is kept (:meth:`.factors_agree`).
After optimisation (:func:`planodom.smoothing.loop_gate.gate_loop_factors`) a loop factor
whose Gaussian twin's squared whitened error exceeds the ``loop_gate_quantile`` of chi2(5)
is removed with its hypothesis (the chain of agreeing loop poses it was confirmed with) and
the graph solved again (with the re-identification gate, :func:`planodom.smoothing.batch._gated`).
On simulated data each factor is compared with the truth (:class:`.loop_records.LoopFactor`).
"""

from __future__ import annotations

from collections.abc import Sequence

import gtsam
import numpy as np

from planodom.config import PlanodomConfig
from planodom.geometry import Plane, invert_transform, pose5_from_transform
from planodom.odometry import RelativePose, Status, estimate_relative_pose
from planodom.odometry.twist_sigma import chi2_quantile as chi2_ppf  # (remembered)
from planodom.smoothing.deskew_noise import DeskewNoise
from planodom.smoothing.graph import GraphUpdate, X
from planodom.smoothing.loop_drift import RunWalk, measured_step_terms, run_drift
from planodom.smoothing.loop_records import Correction, LoopFactor, LoopMatch
from planodom.smoothing.loops import MAX_ROTATION_BOUND_DEG, LoopClosingBuilder
from planodom.smoothing.match_fit import (
    _extent,
    ambiguity,
    epoch_ambiguity,
    non_parallel,
    offset_residuals,
    spanning_epoch,
)
from planodom.smoothing.noise import between_covariance, with_robust_kernel
from planodom_factors.pose5 import pose5_factor

#: An old epoch is a loop candidate only when the route between it and the current epoch is
#: at least this many times their predicted distance plus the candidate radius (a revisit).
REVISIT_RATIO = 3.0
#: Robust kernel of loop factors when the config asks for none, in sigmas (gtsam's
#: Cauchy default at 95 % efficiency, as :data:`planodom.smoothing.noise.ROBUST_DEFAULTS`).
CAUCHY_K = 2.3849


class CandidateLoopBuilder(LoopClosingBuilder):
    """:class:`LoopClosingBuilder` that also adds 5-DoF loop-candidate factors.

    Attributes:
        loop_factors: every loop factor added, in order (global factor indices).
        candidate_attempts: epochs at which old epochs were tried. loop_deskew: the loop
            factors' own deskewing model (``smoothing.loop_factor_deskew``; batch sets it).
    """

    def __init__(self, config: PlanodomConfig, T_world_first: np.ndarray | None = None) -> None:
        super().__init__(config, T_world_first)
        self.loop_factors: list[LoopFactor] = []
        self.candidate_attempts = 0
        self._graph_size = 0  # factors added by the epochs before (batch pushes them all)
        self._positions: list[np.ndarray] = []
        #: chained (xy, yaw) variance sums as :attr:`variances`, but with the measured yaw
        #: of rotation-only epochs (the map's bounds take the fallback's for them)
        self._variances: list[np.ndarray] = []
        self._arrays = (np.zeros(0), np.zeros((0, 2)), np.zeros((0, 2)))  # see _history
        self._last_verified: RelativePose | None = None
        self._group = -1  # hypothesis of the latest loop factors (chained agreeing poses)
        self._walk, self._yaw_walk = RunWalk(), RunWalk()  # "run" drift: bridged xy, yaw
        #: epochs a measured relative pose (delta <= D) fixed the translation to or from
        self._translated: set[int] = set()
        self._aliased = -1  # the last epoch ``loop_candidate_aliases`` found ambiguous
        #: (k, spanning epoch) of the map's accepted correction (``loop_candidate_reference``)
        self._spanning_reference: tuple[int, int] | None = None
        self.loop_deskew: DeskewNoise | None = None

    def add_epoch(
        self, planes: Sequence[Plane], relatives: Sequence[RelativePose] = (), min_epoch: int = 0
    ) -> GraphUpdate:
        """:meth:`LoopClosingBuilder.add_epoch`, counting the graph's factors (batch: in order)."""
        k, c = self.n_epochs, self.config
        var_t, var_r = c.fallback_translation_sigma_m**2, c.fallback_rotation_sigma_rad**2
        step = yaw = None
        for r in relatives:
            if r.curr == k and r.delta <= c.delta_max and r.measured and r.translation_observed:
                self._translated |= {r.prev, r.curr}
        for r in relatives:  # the yaw of a rotation-only epoch is measured too
            if r.curr == k and r.delta == 1 and r.measured and r.covariance is not None:
                var_r, yaw, var_t, step = measured_step_terms(r, var_t, step)
        if c.loop_candidate_drift == "run" and k:
            var_t = self._walk.variance(step, var_t)  # the run's drift (:class:`.RunWalk`)
            if c.loop_drift_yaw == "run":
                var_r = self._yaw_walk.variance(yaw, var_r)
        last = self._variances[-1] if k else np.zeros(2)
        self._variances.append(last + (var_t, var_r) if k else last)
        update = super().add_epoch(planes, relatives, min_epoch)
        self._graph_size += update.factors.size()
        return update

    def _candidate_drift(self, spans: list[tuple[int, int]]) -> np.ndarray:
        """(3, 3) covariance of the chained guess's (yaw, x, y) drift over ``spans`` for the
        loop candidates' agreement (``loop_candidate_drift``): as the map's verification's
        (:meth:`LoopClosingBuilder._drift_covariance`), "run" the run's (:class:`.RunWalk`)."""
        c = self.config
        if c.loop_candidate_drift != "run":
            return self._drift_covariance(spans, c.loop_candidate_drift == "stated")
        travelled, variances, _ = self._history()
        return run_drift(travelled, variances, spans, self.full_config)

    def _drift_covariance(
        self, spans: list[tuple[int, int]], stated: bool = False, run: bool = False
    ) -> np.ndarray:
        """:meth:`LoopClosingBuilder._drift_covariance`; not ``stated``, with ``run`` or
        ``loop_verify_drift`` "run" the run's, as the loop candidates' (:func:`.run_drift`)."""
        if stated or not (run or self.config.loop_verify_drift == "run"):
            return super()._drift_covariance(spans, stated)
        return run_drift(self.travelled, self._variances, spans, self.full_config)

    def _reidentify(self, update: GraphUpdate) -> None:
        if self.config.loop_refuse_ambiguous == "run":  # the alias test's map drift: the run's
            self._stated[-1] = self._variances[-1] * (0.5, 1.0)  # (the stated ones unused)
        super()._reidentify(update)
        k, c = update.epoch, self.config
        self._positions.append(self.poses[k][:2, 3].copy())
        if c.loop_candidates and k % c.loop_candidate_every_epochs == 0:
            self._close_to_old_epoch(update)

    def _predicted(self, k: int) -> np.ndarray:
        """(4, 4) predicted ``T_world_k`` in the map's frame (the tracked correction)."""
        tracked = self.config.loop_verify == "tracked" and self._reference is not None
        return self.correction @ self.poses[k] if tracked else self.poses[k]

    def _history(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per epoch so far: distance driven (E,) m, chained (xy, yaw) variance sums (E, 2)
        and predicted xy positions (E, 2) m, as arrays extended by the epochs added since
        the last call (rebuilding them from the lists at every epoch cost O(E^2): a fifth
        of a 1 365-epoch lap's time in cProfile)."""
        travelled, variances, positions = self._arrays
        n, m = len(travelled), min(len(self._positions), len(self.travelled), len(self._variances))
        if n < m:
            travelled = np.concatenate([travelled, self.travelled[n:m]])
            variances = np.concatenate([variances, np.reshape(self._variances[n:m], (-1, 2))])
            positions = np.concatenate([positions, np.reshape(self._positions[n:m], (-1, 2))])
            self._arrays = travelled, variances, positions
        return self._arrays

    def _bounds(self, k: int, old: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Translation (m) and rotation (deg) bounds (each like ``old``) of the drift
        between k's prediction and the old epochs ``old`` (int array): ``loop_sigmas``
        standard deviations of the odometry chained from e to k (or, tracked, from the
        accepted correction's epoch to k and from its map epoch to e), translation and
        rotation times the distance driven, plus the minima. Not capped by the drift
        fraction as the map matches are: after an odometry failure the covariance, not
        the typical drift, says how far off the prediction may be."""
        c = self.config
        travelled, variances, _ = self._history()
        tracked = c.loop_verify == "tracked" and self._reference is not None
        a, b = (k, k) if not tracked else self._map_reference()
        # spans (a, k) and (b, e): |cumulative(k) - cumulative(a)| + |cumulative(e) - ...(b)|
        span = lambda v: np.abs(v[k] - v[a]) + np.abs(v[old] - v[b])  # noqa: E731
        distance, var_t, var_r = span(travelled), span(variances[:, 0]), span(variances[:, 1])
        grown = c.loop_sigmas * (np.sqrt(var_t) + np.sqrt(var_r) * distance)
        prior_deg = self.full_config.association.prior_rotation_deg
        rotation = prior_deg + c.loop_sigmas * np.degrees(np.sqrt(var_r))
        return c.loop_min_translation_m + grown, np.minimum(rotation, MAX_ROTATION_BOUND_DEG)

    def _bounded(self, translation: float, rotation_deg: float) -> PlanodomConfig:
        """The odometry's config with LDA bounds around the prior of ``translation`` (m)
        and ``rotation_deg``."""
        odometry = self.full_config.odometry
        changes = {
            "association.prior_translation_m": translation,
            "association.prior_rotation_deg": rotation_deg,
            "odometry.retry_without_prior": False,
            # as for the map matches (LoopClosingBuilder._match_config): a direction is
            # measured when the match narrows the bounds' sigma
            "odometry.refine_max_sigma_m": max(
                odometry.refine_max_sigma_m, translation / self.config.loop_sigmas
            ),
        }
        return self.full_config.updated_fields(changes, source="loop candidate bounds")

    def old_epoch_candidates(self, k: int) -> list[int]:
        """Old epochs within reach of epoch k's prediction, nearest first (module docstring)."""
        c = self.config
        last = k - c.loop_min_gap_epochs
        if last < 0:
            return []
        old = np.arange(last + 1)
        position = self._predicted(k)[:2, 3]
        travelled, _, positions = self._history()
        dist = np.linalg.norm(positions[: last + 1] - position, axis=1)
        reach = c.loop_candidate_radius_m + self._bounds(k, old)[0]
        # a revisit: the route left and came back (driven at least REVISIT_RATIO times
        # as far as the places are apart); along a straight street an old epoch is no
        # loop, and its long-baseline relative pose only repeats the odometry
        driven = travelled[k] - travelled[: last + 1]
        reach = np.where(driven >= REVISIT_RATIO * (dist + c.loop_candidate_radius_m), reach, -1.0)
        out: list[int] = []
        for e in np.flatnonzero(dist <= reach)[np.argsort(dist[dist <= reach], kind="stable")]:
            e = int(e)
            if len(self.planes[e]) < c.loop_candidate_min_inliers:
                continue
            if c.loop_candidate_old == "translated" and e not in self._translated:
                continue  # its planes agreed with no neighbour's (loop_candidate_old)
            if all(abs(e - o) >= c.loop_candidate_every_epochs for o in out):
                out.append(e)
            if len(out) == c.loop_candidate_max:
                break
        return out

    def match_old_epoch(self, k: int, e: int) -> RelativePose | None:
        """The paper's odometry between old epoch e and k under the grown bounds around
        the prediction, or None when its consensus does not verify it."""
        c = self.config
        prior = invert_transform(self.poses[e]) @ self._predicted(k)
        translation, rotation = self._bounds(k, np.array([e]))
        cfg = self._bounded(float(translation[0]), float(rotation[0]))
        rel = estimate_relative_pose(self.planes[e], self.planes[k], cfg, prior=prior)
        pairs = np.asarray(rel.associations, dtype=int).reshape(-1, 2)
        if rel.status is not Status.OK or len(pairs) < c.loop_candidate_min_inliers:
            return None
        normals = np.stack([self.planes[k][i].normal for i in pairs[:, 1]])
        if not non_parallel(normals):
            return None
        T_k_e = invert_transform(np.asarray(rel.T_prev_curr, dtype=float))
        for i, j in pairs:  # the paper's overlap: matched planes must share their extent
            c_old, r_old = _extent(self.planes[e][i], T_k_e)
            c_cur, r_cur = _extent(self.planes[k][j], np.eye(4))
            if np.linalg.norm(c_old - c_cur) - r_old - r_cur > c.loop_candidate_overlap_m:
                return None
        test = c.loop_refuse_ambiguous not in ("off", "run") or c.loop_candidate_aliases != "off"
        if test and self._ambiguous(e, k, rel, pairs, prior, translation[0]):
            return None
        return RelativePose(
            np.asarray(rel.T_prev_curr, dtype=float), rel.covariance, rel.status,
            pairs, rel.sources, prev=e, curr=k,
        )  # fmt: skip

    def _ambiguous(
        self, e: int, k: int, rel: RelativePose, pairs: np.ndarray, prior: np.ndarray, bound: float
    ) -> bool:
        """Whether a competing hypothesis (one pair's old plane swapped for a parallel
        plane of epoch e, the pose shifted to fit) explains the pairs about as well as
        the match, within chi2(1) at ``loop_gate_quantile``, under the prediction's prior
        (the bound ``bound`` m as ``loop_sigmas`` standard deviations: the chained
        odometry's, not capped) (:func:`planodom.smoothing.match_fit.ambiguity`); with
        ``loop_candidate_aliases`` "both_epochs" (the test alone when
        ``loop_refuse_ambiguous`` is "off"), also a parallel plane of epoch k, and a
        parallel plane within the noise of the tied one is no competitor
        (:func:`planodom.smoothing.match_fit.epoch_ambiguity`)."""
        c = self.config
        T = np.asarray(rel.T_prev_curr, dtype=float).copy()
        T[:2, 3] = prior[:2, 3]  # the match's rotation at the predicted position
        angle = self.full_config.association.strict_normal_deg
        sigma, limit = c.default_plane_offset_sigma_m, chi2_ppf(c.loop_gate_quantile, 1)
        if c.loop_candidate_aliases != "off":
            old, curr = self.planes[e], self.planes[k]
            spacing = c.loop_candidate_aliases == "spacing"
            level = self.full_config.odometry.z_plane_max_tilt_deg
            args = (bound / c.loop_sigmas, sigma, angle, limit, spacing, level)
            if epoch_ambiguity(old, curr, pairs, T, *args) <= limit:
                self._aliased = k
                return True
            if c.loop_refuse_ambiguous in ("off", "run"):
                return False
        fit = offset_residuals(self.planes[e], self.planes[k], pairs, T, sigma, angle, np.zeros(0))
        return ambiguity(fit, bound / c.loop_sigmas, sigma) <= limit

    def _close_to_old_epoch(self, update: GraphUpdate) -> None:
        """Try the old-epoch candidates of this epoch; the first verified one is kept if it
        agrees with the last verified one, at most ``loop_candidate_confirm_epochs`` before
        (:meth:`_agrees`), which is then added too."""
        k, c = update.epoch, self.config
        candidates = self.old_epoch_candidates(k)
        if candidates:
            self.candidate_attempts += 1
        for e in candidates:
            rel = self.match_old_epoch(k, e)
            if rel is None and self._aliased == k:
                return  # an aliased place: other old epochs show less of it, not more
            if rel is None:
                continue
            if not self._agrees_with_map(rel) or not self._plausible(rel):
                continue
            last, self._last_verified = self._last_verified, rel
            n, old = c.loop_candidate_confirm_epochs, c.loop_candidate_confirm_old
            if last is None or k - last.curr > n or (old and abs(rel.prev - last.prev) > n):
                return  # (loop_candidate_confirm_old: far-apart old epochs agree on anything)
            if not self._agrees(last, rel):
                return
            previous = self.loop_factors[-1] if self.loop_factors else None
            if previous is None or (previous.epoch, previous.old) != (last.curr, last.prev):
                self._group += 1  # a new hypothesis: its first two agreeing poses
                self._add_loop_factor(update, last)
            self._add_loop_factor(update, rel)
            return

    def _correction(self, rel: RelativePose) -> np.ndarray:
        """(4, 4) the world correction of the chained guess a loop pose implies: epoch
        ``rel.curr`` placed at ``poses[prev] @ T_prev_curr`` instead of ``poses[curr]``."""
        T_world_curr = self.poses[rel.prev] @ np.asarray(rel.T_prev_curr, dtype=float)
        return T_world_curr @ invert_transform(self.poses[rel.curr])

    def _agrees(self, first: RelativePose, second: RelativePose) -> bool:
        """Whether two verified loop poses imply the same correction of the chained guess:
        chi2(3) at ``loop_gate_quantile`` on (yaw, x, y) of epoch ``second.curr`` placed by
        both, under their covariances and the chained odometry's between their epochs."""
        spans = [(first.curr, second.curr), (first.prev, second.prev)]
        cov = self._candidate_drift(spans)
        for rel in (first, second):
            if rel.covariance is None:
                return False
            cov += np.asarray(rel.covariance, dtype=float).reshape(5, 5)[2:, 2:]
        T_a = self._correction(first) @ self.poses[second.curr]
        T_b = self._correction(second) @ self.poses[second.curr]
        v = pose5_from_transform(invert_transform(T_a) @ T_b)[2:]
        return float(v @ np.linalg.solve(cov, v)) <= chi2_ppf(self.config.loop_gate_quantile, 3)

    def factors_agree(self, a: LoopFactor, b: LoopFactor) -> bool:
        """Whether two loop factors imply the same correction of the chained guess
        (:meth:`corrections_agree`): pairwise consistency,
        :func:`planodom.smoothing.loop_gate.consistent_hypotheses`."""
        return self.corrections_agree(
            Correction.of_factor(a, self.poses), Correction.of_factor(b, self.poses)
        )

    def corrections_agree(self, a: Correction, b: Correction) -> bool:
        """Whether two corrections of the chained guess (of loop factors or accepted map
        matches) agree, as :meth:`_agrees`: chi2(3) at ``loop_gate_quantile`` on (yaw, x, y)
        of epoch ``b.epoch`` placed by both, under their covariances and the chained
        odometry's drift (``loop_candidate_drift``) between their current and between
        their old epochs."""
        cov = self._candidate_drift([(a.epoch, b.epoch), (a.old, b.old)])
        cov = cov + a.covariance + b.covariance
        T_b = self.poses[b.epoch]
        v = pose5_from_transform(invert_transform(a.W @ T_b) @ b.W @ T_b)[2:]
        return float(v @ np.linalg.solve(cov, v)) <= chi2_ppf(self.config.loop_gate_quantile, 3)

    def _verify(self, match: LoopMatch, T_world_curr: np.ndarray, full: bool) -> str:
        """:meth:`LoopClosingBuilder._verify`, noting on ``match`` its map epochs (``seen``,
        ``spanning``) and rank, for ``loop_consistency`` "hypotheses_and_map"."""
        seen = [self.landmarks[j].last_seen[0] for j, _ in match.ties]  # type: ignore[index]
        match.seen, match.full = min(seen), full
        normals = np.array([self.landmarks[j].plane_world[:3] for j, _ in match.ties])
        match.spanning = spanning_epoch(seen, normals)
        reference = self._reference
        verdict = super()._verify(match, T_world_curr, full)
        if self._reference is not reference:  # a new accepted correction
            self._spanning_reference = (match.epoch, match.spanning)
        return verdict

    def _map_reference(self) -> tuple[int, int]:
        """(k, map epoch) of the map's accepted correction as the loop candidates' bounds
        and agreement take it (``loop_candidate_reference``: the map epoch the earliest
        or the spanning last sighting of its match's tied walls)."""
        if self.config.loop_candidate_reference == "spanning" and self._spanning_reference:
            return self._spanning_reference
        return self._reference  # type: ignore[return-value]

    def _agrees_with_map(self, rel: RelativePose) -> bool:
        """Whether a verified loop pose agrees with the map's accepted correction (the
        tracked re-identification, :meth:`LoopClosingBuilder._verify`) within the drift
        since it was taken and between the map parts (chi2(3) at ``loop_gate_quantile``);
        True while no correction is accepted."""
        if self._reference is None or rel.covariance is None:
            return self._reference is None
        k_ref, seen_ref = self._map_reference()
        spans = [(k_ref, rel.curr), (seen_ref, rel.prev)]
        own = np.asarray(rel.covariance, dtype=float).reshape(5, 5)[2:, 2:]
        cov = self._candidate_drift(spans) + own
        T_a = self.correction @ self.poses[rel.curr]
        T_b = self._correction(rel) @ self.poses[rel.curr]
        v = pose5_from_transform(invert_transform(T_a) @ T_b)[2:]
        return float(v @ np.linalg.solve(cov, v)) <= chi2_ppf(self.config.loop_gate_quantile, 3)

    def _plausible(self, rel: RelativePose) -> bool:
        """``loop_candidate_drift`` "run", no correction accepted by the map: whether the
        correction of the chained guess a verified loop pose implies is within the drift
        of the chained odometry between its epochs (chi2(3) at ``loop_gate_quantile``):
        an aliased place farther off than the run can have drifted is no loop. True
        otherwise (the map's correction is compared by :meth:`_agrees_with_map`; the
        other modes rely on the association bounds alone)."""
        if self.config.loop_candidate_drift != "run" or self._reference is not None:
            return True
        if rel.covariance is None:
            return False
        own = np.asarray(rel.covariance, dtype=float).reshape(5, 5)[2:, 2:]
        cov = self._candidate_drift([(rel.prev, rel.curr)]) + own
        v = pose5_from_transform(self._correction(rel))[2:]
        return float(v @ np.linalg.solve(cov, v)) <= chi2_ppf(self.config.loop_gate_quantile, 3)

    def _add_loop_factor(self, update: GraphUpdate, rel: RelativePose) -> None:
        """A robust 5-DoF factor ``X(prev) - X(curr)`` for a verified loop pose (its
        Gaussian twin in ``update.gaussian``), recorded in :attr:`loop_factors`."""
        c, e, k = self.config, rel.prev, rel.curr
        model = self.deskew or self.loop_deskew  # (none: no deskewing error; instant: zero)
        dsk = None if model is None else model.loop_covariance(e, k, rel.T_prev_curr)
        cov = between_covariance(rel, c, dsk)
        base = gtsam.noiseModel.Gaussian.Covariance(cov)
        if c.robust_kernel != "none":
            noise = with_robust_kernel(base, c)
        else:
            cauchy = gtsam.noiseModel.mEstimator.Cauchy.Create(CAUCHY_K)
            noise = gtsam.noiseModel.Robust.Create(cauchy, base)
        index = update.factors.size()
        update.gaussian[index] = pose5_factor(X(e), X(k), rel.T_prev_curr, base)
        update.factors.add(pose5_factor(X(e), X(k), rel.T_prev_curr, noise))
        self.loop_factors.append(
            LoopFactor(k, e, np.asarray(rel.T_prev_curr, dtype=float), cov,
                       len(rel.associations), self._graph_size + index, self._group,
                       associations=rel.associations)
        )  # fmt: skip
