"""Loop candidates in batch smoothing: 5-DoF relative poses to old epochs (issue 14).

Where the chained odometry's covariance has grown, the map re-identification
(:mod:`planodom.smoothing.loops`) may find no landmark near the predicted pose (the
prediction is metres off after an odometry failure, or the old landmarks never formed).
:class:`CandidateLoopBuilder` then compares whole epochs, at every
``loop_candidate_every_epochs``-th epoch k:

1. candidates: old epochs e at least ``loop_min_gap_epochs`` before k whose (chained)
   position lies within ``loop_candidate_radius_m`` plus the translation bound of the
   drift between them (``loop_sigmas`` standard deviations of the chained odometry, at
   most ``loop_drift_fraction`` of the distance driven, as for the map matches) of k's
   predicted position (the tracked correction applied, ``loop_verify`` "tracked"); the
   nearest ``loop_candidate_max``, each ``loop_min_gap_epochs`` apart from the others;
2. the paper's odometry (:func:`planodom.odometry.estimate_relative_pose`: LDA under the
   grown bounds around the predicted ``T_e_k``, WOCSC, strict association) between the
   planes of e and k;
3. verification by its consensus: status OK (5 DoF) and at least
   ``loop_candidate_min_inliers`` strict associations spanning non-parallel normals;
4. the first verified one becomes a 5-DoF between factor ``X(e) - X(k)``
   (:func:`factors.pose5.pose5_factor`) with the odometry's covariance and a robust
   kernel (``robust_kernel``, Cauchy when "none": a loop factor is never trusted blindly).

After optimisation (:func:`gate_loop_factors`) a loop factor whose Gaussian twin's
squared whitened error exceeds the ``loop_gate_quantile`` of chi2(5) is removed and the
graph solved again (with the re-identification gate, :func:`planodom.smoothing.batch._gated`).
On simulated data each factor is compared with the true relative pose
(:class:`planodom.smoothing.loop_records.LoopFactor`).
"""

from __future__ import annotations

from collections.abc import Sequence

import gtsam
import numpy as np
from scipy.stats import chi2

from planodom.config import PlanodomConfig
from planodom.geometry import Plane, invert_transform
from planodom.odometry import RelativePose, Status, estimate_relative_pose
from planodom.smoothing.graph import GraphUpdate, X
from planodom.smoothing.loop_records import LoopFactor
from planodom.smoothing.loops import MAX_ROTATION_BOUND_DEG, LoopClosingBuilder, non_parallel
from planodom.smoothing.noise import between_covariance, with_robust_kernel
from planodom_factors.pose5 import pose5_factor

#: Robust kernel of loop factors when the config asks for none, in sigmas (gtsam's
#: Cauchy default at 95 % efficiency, as :data:`planodom.smoothing.noise.ROBUST_DEFAULTS`).
CAUCHY_K = 2.3849


class CandidateLoopBuilder(LoopClosingBuilder):
    """:class:`LoopClosingBuilder` that also adds 5-DoF loop-candidate factors.

    Attributes:
        loop_factors: every loop factor added, in order (global factor indices).
        candidate_attempts: epochs at which old epochs were tried.
    """

    def __init__(self, config: PlanodomConfig, T_world_first: np.ndarray | None = None) -> None:
        super().__init__(config, T_world_first)
        self.loop_factors: list[LoopFactor] = []
        self.candidate_attempts = 0
        self._graph_size = 0  # factors added by the epochs before (batch pushes them all)
        self._positions: list[np.ndarray] = []

    def add_epoch(
        self, planes: Sequence[Plane], relatives: Sequence[RelativePose] = (), min_epoch: int = 0
    ) -> GraphUpdate:
        """:meth:`LoopClosingBuilder.add_epoch`, keeping count of the graph's factors (the
        batch loop pushes every update whole, in order)."""
        update = super().add_epoch(planes, relatives, min_epoch)
        self._graph_size += update.factors.size()
        return update

    def _reidentify(self, update: GraphUpdate) -> None:
        super()._reidentify(update)
        k, c = update.epoch, self.config
        self._positions.append(self.poses[k][:2, 3].copy())
        if c.loop_candidates and k % c.loop_candidate_every_epochs == 0:
            self._close_to_old_epoch(update)

    def _predicted(self, k: int) -> np.ndarray:
        """(4, 4) predicted ``T_world_k`` in the map's frame (the tracked correction)."""
        tracked = self.config.loop_verify == "tracked" and self._reference is not None
        return self.correction @ self.poses[k] if tracked else self.poses[k]

    def _spans(self, k: int, e: int) -> list[tuple[int, int]]:
        """Epoch spans of the chained odometry whose drift separates k's prediction from e."""
        tracked = self.config.loop_verify == "tracked" and self._reference is not None
        if not tracked:
            return [(e, k)]
        assert self._reference is not None
        return [(self._reference[0], k), (self._reference[1], e)]

    def _translation_bound(self, k: int, e: int) -> float:
        """Translation bound of the drift between k's prediction and old epoch e, m (the
        one :meth:`LoopClosingBuilder._match_config` sets)."""
        c = self.config
        distance, var_t, var_r = self._chain(self._spans(k, e))
        grown = c.loop_sigmas * (np.sqrt(var_t) + np.sqrt(var_r) * distance)
        return c.loop_min_translation_m + min(grown, c.loop_drift_fraction * distance)

    def old_epoch_candidates(self, k: int) -> list[int]:
        """Old epochs within reach of epoch k's prediction, nearest first (module docstring)."""
        c = self.config
        last = k - c.loop_min_gap_epochs
        if last < 0:
            return []
        position = self._predicted(k)[:2, 3]
        dist = np.linalg.norm(np.asarray(self._positions[: last + 1]) - position, axis=1)
        out: list[int] = []
        for e in np.argsort(dist, kind="stable"):
            if len(out) == c.loop_candidate_max or dist[e] > c.loop_candidate_radius_m + 50.0:
                break
            e = int(e)
            if len(self.planes[e]) < c.loop_candidate_min_inliers:
                continue
            if any(abs(e - o) < c.loop_candidate_every_epochs for o in out):
                continue
            if dist[e] <= c.loop_candidate_radius_m + self._translation_bound(k, e):
                out.append(e)
        return out

    def match_old_epoch(self, k: int, e: int) -> RelativePose | None:
        """The paper's odometry between old epoch e and k under the grown bounds around
        the prediction, or None when its consensus does not verify it."""
        c = self.config
        prior = invert_transform(self.poses[e]) @ self._predicted(k)
        cfg = self._match_config(self._spans(k, e))
        rel = estimate_relative_pose(self.planes[e], self.planes[k], cfg, prior=prior)
        pairs = np.asarray(rel.associations, dtype=int).reshape(-1, 2)
        if rel.status is not Status.OK or len(pairs) < c.loop_candidate_min_inliers:
            return None
        normals = np.stack([self.planes[k][i].normal for i in pairs[:, 1]])
        if not non_parallel(normals):
            return None
        assert cfg.association.prior_rotation_deg <= MAX_ROTATION_BOUND_DEG
        return RelativePose(
            np.asarray(rel.T_prev_curr, dtype=float), rel.covariance, rel.status,
            pairs, rel.sources, prev=e, curr=k,
        )  # fmt: skip

    def _close_to_old_epoch(self, update: GraphUpdate) -> None:
        k, c = update.epoch, self.config
        candidates = self.old_epoch_candidates(k)
        if candidates:
            self.candidate_attempts += 1
        for e in candidates:
            rel = self.match_old_epoch(k, e)
            if rel is None:
                continue
            cov = between_covariance(rel, c)
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
                LoopFactor(k, e, rel.T_prev_curr, cov, len(rel.associations),
                           self._graph_size + index)
            )  # fmt: skip
            return


def gate_loop_factors(
    builder: object,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    values: gtsam.Values,
) -> int:
    """Remove the loop factors (of a :class:`CandidateLoopBuilder`; none for other
    builders) whose squared whitened error at ``values`` exceeds the
    ``loop_gate_quantile`` of chi2(5) from ``graph`` (and their Gaussian twins); returns
    how many. Each factor's chi2 is recorded."""
    factors: list[LoopFactor] = getattr(builder, "loop_factors", [])
    if not factors:
        return 0
    limit = float(chi2.ppf(builder.config.loop_gate_quantile, 5))  # type: ignore[attr-defined]
    removed = 0
    for f in factors:
        if f.removed:
            continue
        f.chi2 = 2.0 * float(gaussian.get(f.factor, graph.at(f.factor)).error(values))
        if f.chi2 > limit:
            graph.remove(f.factor)
            gaussian.pop(f.factor, None)
            f.removed = True
            removed += 1
    return removed
