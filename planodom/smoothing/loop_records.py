"""Records of loop closure (:mod:`planodom.smoothing.loops`): each epoch's match against
the map with the verification's verdict, each re-identified observation with the gate's
verdict and, on simulated data, the truth; and their counts."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import gtsam
import numpy as np

from planodom.geometry import invert_transform
from planodom.smoothing.match_fit import OffsetFit
from planodom.smoothing.tie_gate import tie_gate_limit
from planodom_factors.pose5 import pose5_error


@dataclass
class Reidentification:
    """One observation re-identified as an old landmark.

    Attributes:
        epoch, plane: the observation. landmark: the old landmark's id.
        factor: index of its plane factor in the whole graph (set by the batch loop).
        truth_plane, truth_landmark: true surface ids of the observation and of the
            landmark's last observation (-1 unknown). removed: refused by the gate.
    """

    epoch: int
    plane: int
    landmark: int
    factor: int
    truth_plane: int = -1
    truth_landmark: int = -1
    removed: bool = False

    @property
    def wrong(self) -> bool:
        """Known to join two different true surfaces."""
        return min(self.truth_plane, self.truth_landmark) >= 0 and (
            self.truth_plane != self.truth_landmark
        )


@dataclass
class LoopMatch:
    """One epoch's match against the map, accepted or refused by the verification.

    Attributes:
        epoch: the current epoch k. oldest: the earliest last-seen epoch of its candidates.
        T_world_pred: (4, 4) the predicted pose of epoch k. T_pred_curr: (4, 4) epoch k
            in the predicted frame as the match places it (identity: prediction exact).
        covariance: (5, 5) the match's own covariance (roll, pitch, yaw, x, y).
        drift: (3, 3) covariance of the (yaw, x, y) drift since the compared correction.
        mahalanobis: squared Mahalanobis distance from the accepted correction.
        ties: (landmark, plane index) pairs. verdict: "accepted" or why refused.
        offsets: of a rotation-only match with ``loop_refuse_misfit``, its ties' offset
            residuals against the parallel map walls (:func:`.match_fit.offset_residuals`).
        misfit: their largest squared whitened residual under ``drift`` (chi2(1)).
        ambiguity: chi2 by which the ties beat their best competing hypothesis (a tie
            swapped for a parallel old plane; :func:`.match_fit.ambiguity`).
        seen: the earliest last sighting of its tied walls (the map epoch it places k
            against; -1 before verification). full: verified on (yaw, x, y), not on yaw
            (both noted by :meth:`.CandidateLoopBuilder._verify`, ``loop_consistency``).
        spanning: the last sighting by which its tied walls span two non-parallel
            normals (:func:`.match_fit.spanning_epoch`; -1 before verification), the map
            epoch it places k against with ``loop_map_epoch`` "spanning".
    """

    epoch: int
    oldest: int
    T_world_pred: np.ndarray
    T_pred_curr: np.ndarray
    covariance: np.ndarray
    drift: np.ndarray
    mahalanobis: float
    ties: list[tuple[int, int]]
    verdict: str = "accepted"
    offsets: OffsetFit | None = None
    misfit: float = np.nan
    ambiguity: float = np.inf
    seen: int = -1
    full: bool = False
    spanning: int = -1


@dataclass(frozen=True)
class Correction:
    """The correction of the chained guess one loop factor or accepted map match implies,
    for pairwise consistency (:meth:`.CandidateLoopBuilder.corrections_agree`).

    Attributes:
        epoch: the current epoch k. old: the old epoch it places k against (a loop
            factor's old epoch; a map match's ``seen``, or its ``spanning``).
        W: (4, 4) world correction: epoch k at ``W @ poses[k]`` (chained guess poses).
        covariance: (3, 3) of its (yaw, x, y), rad^2 and m^2.
    """

    epoch: int
    old: int
    W: np.ndarray
    covariance: np.ndarray

    @staticmethod
    def of_factor(f: LoopFactor, poses: dict[int, np.ndarray]) -> Correction:
        """A loop factor's: epoch k at ``poses[old] @ T_old_curr``."""
        W = poses[f.old] @ f.T_old_curr @ invert_transform(poses[f.epoch])
        return Correction(f.epoch, f.old, W, f.covariance[2:, 2:])

    @staticmethod
    def of_match(m: LoopMatch, poses: dict[int, np.ndarray], spanning: bool = False) -> Correction:
        """An accepted map match's: epoch k where the map places it, against its ``seen``
        (``spanning``: its ``spanning`` where noted)."""
        W = m.T_world_pred @ m.T_pred_curr @ invert_transform(poses[m.epoch])
        old = m.spanning if spanning and m.spanning >= 0 else m.seen
        return Correction(m.epoch, old, W, m.covariance[2:, 2:])


def reidentification_counts(
    reids: Sequence[Reidentification],
    same_plane: Callable[[int, int], bool] | None = None,
) -> dict[str, int]:
    """Accepted, removed and (on simulated data) wrong re-identifications, kept / removed.

    ``same_plane(a, b)``: whether true surfaces a and b lie in one plane (two segments of
    one facade are one plane to a plane map); default: same surface id.
    """

    def wrong(r: Reidentification) -> bool:
        if same_plane is None or min(r.truth_plane, r.truth_landmark) < 0:
            return r.wrong
        return not same_plane(r.truth_plane, r.truth_landmark)

    kept = [r for r in reids if not r.removed]
    return {
        "reidentified": len(kept),
        "reidentified_removed": len(reids) - len(kept),
        "wrong_kept": sum(wrong(r) for r in kept),
        "wrong_removed": sum(wrong(r) for r in reids if r.removed),
    }


@dataclass
class LoopFactor:
    """One loop candidate that became a 5-DoF between factor
    (:mod:`planodom.smoothing.loop_candidates`).

    Attributes:
        epoch: the current epoch k. old: the old epoch e.
        T_old_curr: (4, 4) the relative pose measured between them (its z unobserved).
        covariance: (5, 5) the factor's covariance in its tangent (rotation vector, rad;
            x, y, m), the odometry's floored (:func:`planodom.smoothing.noise.between_covariance`)
            plus both epochs' deskewing error (``smoothing.deskew_noise``).
        inliers: strict associations that verified it.
        factor: index of the factor in the whole graph.
        group: its hypothesis: loop factors confirmed by each other in a chain share it.
        chi2: squared whitened error of its Gaussian twin at the last estimate (nan
            before optimisation). increase: what its hypothesis costs the rest of the
            graph (:func:`planodom.smoothing.loop_gate.test_hypotheses`).
            removed: refused by the gate or that test after optimisation.
        associations: (L, 2) the strict plane associations (index in the old epoch's
            planes, index in the current's) it was solved from (None: not recorded).
    """

    epoch: int
    old: int
    T_old_curr: np.ndarray
    covariance: np.ndarray
    inliers: int
    factor: int
    group: int = 0
    chi2: float = float("nan")
    increase: float = float("nan")
    removed: bool = False
    associations: np.ndarray | None = None

    def truth_error(self, gt_poses: np.ndarray) -> np.ndarray:
        """(5,) the factor's error at the true poses ``gt_poses`` (E, 4, 4): rotation
        vector (rad) and x, y (m) of the measured against the true relative pose."""
        return pose5_error(self.T_old_curr, gt_poses[self.old], gt_poses[self.epoch])[0]

    def wrong(self, gt_poses: np.ndarray, n_sigma: float = 3.0) -> bool:
        """Whether it disagrees with the truth by more than ``n_sigma`` of its own
        standard deviation in any of the 5 components."""
        sigma = np.sqrt(np.diag(self.covariance))
        return bool(np.any(np.abs(self.truth_error(gt_poses)) > n_sigma * sigma))


def loop_factor_counts(
    factors: Sequence[LoopFactor], gt_poses: np.ndarray | None
) -> dict[str, int]:
    """Loop-candidate factors kept and removed, and with the truth the wrong ones
    (:meth:`LoopFactor.wrong`) and the largest horizontal error of a kept one (cm)."""
    kept = [f for f in factors if not f.removed]
    out = {"loop_factors": len(kept), "loop_factors_removed": len(factors) - len(kept)}
    if gt_poses is not None:
        out["loop_factors_wrong_kept"] = sum(f.wrong(gt_poses) for f in kept)
        out["loop_factors_wrong_removed"] = sum(f.wrong(gt_poses) for f in factors if f.removed)
        xy = [float(np.linalg.norm(f.truth_error(gt_poses)[3:])) for f in kept]
        out["loop_factors_max_error_cm"] = round(100 * max(xy, default=0.0))
    return out


def graph_without(
    graph: gtsam.NonlinearFactorGraph,
    drop: set[int],
    gaussian: dict[int, gtsam.NonlinearFactor] | None = None,
) -> gtsam.NonlinearFactorGraph:
    """``graph`` without the factors ``drop`` (indices); Gaussian twins where given."""
    twins = gaussian or {}
    out = gtsam.NonlinearFactorGraph()
    for i in range(graph.size()):
        if i not in drop and graph.at(i) is not None:
            out.add(twins.get(i, graph.at(i)))
    return out


def gate_reidentifications(
    builder: Any,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    values: gtsam.Values,
) -> int:
    """Remove the re-identified factors inconsistent with ``values`` (see module
    docstring) from ``graph`` (and their Gaussian twins); returns how many."""
    c = builder.config
    ties = {r.factor for r in builder.reidentifications}
    tracked = [2.0 * f.error(values) for i, f in gaussian.items() if i not in ties and f.dim() == 3]
    limit = tie_gate_limit(np.asarray(tracked), c.loop_gate_quantile, c.loop_tie_gate_limit)
    failed = set()
    for r in builder.reidentifications:
        if not r.removed and 2.0 * gaussian.get(r.factor, graph.at(r.factor)).error(values) > limit:
            failed.add(r.epoch)
    removed = 0
    for r in builder.reidentifications:
        if not r.removed and r.epoch in failed:  # one match, one hypothesis: all out
            graph.remove(r.factor)
            gaussian.pop(r.factor, None)
            r.removed = True
            removed += 1
    builder.stats.reidentified_removed += removed
    return removed
