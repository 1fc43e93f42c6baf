"""Loop closure in batch smoothing: a global plane map, re-identified by geometry alone.

The map is the graph's landmarks, each kept in the world frame of the chained initial
guess with its extent (the support of its last accepted observation: centroid and
radius). At every epoch k (:meth:`LoopClosingBuilder._reidentify`):

1. candidates: landmarks unseen for ``loop_min_gap_epochs`` whose support comes within
   ``loop_radius_m`` of the predicted position (the chained guess ``T_k``);
2. they are expressed in the predicted frame ``T_k`` and matched against the epoch's
   planes with the paper's machinery (:func:`planodom.odometry.estimate_relative_pose`:
   LDA dihedral-angle pairs with absolute constraints around the prediction, WOCSC,
   strict association). The bounds grow with the drift since the candidates were last
   seen: ``loop_min_translation_m + loop_drift_fraction * distance driven`` and
   ``prior_rotation_deg + loop_rotation_deg_per_m * distance`` (at most 45 deg);
3. a match of full rank (status OK) with at least ``loop_min_matches`` strict
   associations spanning two non-parallel normals is accepted: each associated plane
   becomes a plane factor (robust kernel) on the OLD landmark instead of on its track's,
   so a revisited wall ties the loop (its track's own landmark then never forms, or
   keeps the observations before the re-identification).

After optimisation (:func:`gate_reidentifications`) every re-identified factor whose
squared whitened error exceeds the ``loop_gate_quantile`` of chi2(3) is removed and the
graph solved again. On simulated data each re-identification is checked against the
planes' true surface ids (``truth_id``): :class:`Reidentification`.
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np
from scipy.stats import chi2

from planodom.config import PlanodomConfig
from planodom.geometry import Plane, invert_transform
from planodom.odometry import Status, estimate_relative_pose
from planodom.smoothing.graph import GraphBuilder, GraphUpdate

#: Largest rotation bound of a re-identification, degrees.
MAX_ROTATION_BOUND_DEG = 45.0


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


def _extent(plane: Plane, T_world_base: np.ndarray) -> tuple[np.ndarray, float]:
    """World centroid and radius of a plane's support (the plane's foot point, 0 m
    radius, when it has none)."""
    sup = plane.support
    if sup is None:
        centroid = -plane.offset * plane.normal
        return T_world_base[:3, :3] @ centroid + T_world_base[:3, 3], 0.0
    radius = float(np.max(np.linalg.norm(sup.polygon - sup.centroid, axis=1), initial=0.0))
    return T_world_base[:3, :3] @ sup.centroid + T_world_base[:3, 3], radius


def non_parallel(normals: np.ndarray, min_angle_deg: float = 10.0) -> bool:
    """Whether two of the unit ``normals`` (N, 3) are at least ``min_angle_deg`` apart."""
    if len(normals) < 2:
        return False
    cross = np.linalg.norm(np.cross(normals[:, None], normals[None]), axis=2)
    return bool(cross.max() >= np.sin(np.radians(min_angle_deg)))


class LoopClosingBuilder(GraphBuilder):
    """:class:`GraphBuilder` that re-identifies planes against the global map.

    Attributes:
        reidentifications: every accepted re-identified observation, in order.
        attempts: epochs matched against the map. travelled: (E,) cumulative distance
            driven along the chained guess, m.
    """

    def __init__(self, config: PlanodomConfig, T_world_first: np.ndarray | None = None) -> None:
        super().__init__(config.smoothing, T_world_first)
        self.full_config = config
        self.reidentifications: list[Reidentification] = []
        self.attempts = 0
        self.travelled: list[float] = []
        self._extents: dict[int, tuple[int, np.ndarray, float]] = {}  # j -> (epoch, c, r)

    def _candidates(self, k: int) -> list[int]:
        """Landmarks unseen for the minimum gap whose support is near the predicted pose."""
        c, position = self.config, self.poses[k][:3, 3]
        out = []
        for j, lm in self.landmarks.items():
            if lm.last_seen is None or lm.last_seen[0] > k - c.loop_min_gap_epochs:
                continue
            e = lm.last_seen[0]
            cached = self._extents.get(j)
            if cached is None or cached[0] != e:
                cached = (e, *_extent(self.planes[e][lm.last_index], self.poses[e]))
                self._extents[j] = cached
            if np.linalg.norm(cached[1] - position) - cached[2] <= c.loop_radius_m:
                out.append(j)
        return out

    def _map_plane(self, j: int, T_pred_world: np.ndarray) -> Plane:
        """Landmark j's last accepted observation in the predicted frame."""
        lm = self.landmarks[j]
        assert lm.last_seen is not None
        e, coefficients = lm.last_seen
        plane = self.planes[e][lm.last_index]
        if plane.normal @ coefficients[:3] < 0:
            plane = plane.flipped()
        return plane.transformed(T_pred_world @ self.poses[e])

    def _match_config(self, distance: float) -> PlanodomConfig:
        c, a = self.config, self.full_config.association
        translation = c.loop_min_translation_m + c.loop_drift_fraction * distance
        rotation = min(
            a.prior_rotation_deg + c.loop_rotation_deg_per_m * distance, MAX_ROTATION_BOUND_DEG
        )
        changes = {
            "association.prior_translation_m": translation,
            "association.prior_rotation_deg": rotation,
            "odometry.retry_without_prior": False,
        }
        return self.full_config.updated(changes, source="loop closure bounds")

    def _reidentify(self, update: GraphUpdate) -> None:
        k, c = update.epoch, self.config
        step = 0.0 if k == 0 else float(np.linalg.norm(self.poses[k][:2, 3] - self.poses[k - 1][:2, 3]))
        self.travelled.append((self.travelled[-1] if self.travelled else 0.0) + step)
        curr = self.planes[k]
        if not c.loop_closure or len(curr) < c.loop_min_matches:
            return
        candidates = self._candidates(k)
        if len(candidates) < c.loop_min_matches:
            return
        self.attempts += 1
        T_pred_world = invert_transform(self.poses[k])
        oldest = min(self.landmarks[j].last_seen[0] for j in candidates)  # type: ignore[index]
        cfg = self._match_config(self.travelled[k] - self.travelled[oldest])
        map_planes = [self._map_plane(j, T_pred_world) for j in candidates]
        rel = estimate_relative_pose(map_planes, curr, cfg, prior=np.eye(4))
        pairs = np.asarray(rel.associations, dtype=int).reshape(-1, 2)
        if rel.status is not Status.OK or len(pairs) < c.loop_min_matches:
            return
        if not non_parallel(np.stack([curr[i].normal for i in pairs[:, 1]])):
            return
        R = np.asarray(rel.T_prev_curr)[:3, :3]
        for m, i in pairs:
            self._tie(update, candidates[m], int(i), map_planes[m].normal @ R)

    def _tie(self, update: GraphUpdate, j: int, i: int, predicted_normal: np.ndarray) -> None:
        """Plane i of this epoch becomes a (robust) factor on old landmark j."""
        k, lm = update.epoch, self.landmarks[j]
        plane = self.planes[k][i]
        if plane.normal @ predicted_normal < 0:
            plane = plane.flipped()
        index = update.factors.size()
        self._plane_factor(lm, k, plane, update.factors, robust=lm.anchor_key is not None)
        self.reidentified[(k, i)] = j
        self.stats.reidentified += 1
        lm.last_epoch = k
        update.timestamps[lm.key] = float(k)
        truth_lm = self.planes[lm.last_seen[0]][lm.last_index].truth_id  # type: ignore[index]
        self.reidentifications.append(
            Reidentification(k, i, j, index, self.planes[k][i].truth_id, truth_lm)
        )


def gate_reidentifications(
    builder: LoopClosingBuilder,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    values: gtsam.Values,
) -> int:
    """Remove the re-identified factors inconsistent with ``values`` (see module
    docstring) from ``graph`` (and their Gaussian twins); returns how many."""
    limit = chi2.ppf(builder.config.loop_gate_quantile, 3)
    removed = 0
    for r in builder.reidentifications:
        if r.removed:
            continue
        factor = gaussian.get(r.factor, graph.at(r.factor))
        if 2.0 * factor.error(values) > limit:
            graph.remove(r.factor)
            gaussian.pop(r.factor, None)
            r.removed = True
            removed += 1
    builder.stats.reidentified_removed += removed
    return removed


def reidentification_counts(builder: GraphBuilder) -> dict[str, int]:
    """Accepted, removed and (on simulated data) wrong re-identifications kept / removed."""
    reids = getattr(builder, "reidentifications", [])
    kept = [r for r in reids if not r.removed]
    return {
        "reidentified": len(kept),
        "reidentified_removed": len(reids) - len(kept),
        "wrong_kept": sum(r.wrong for r in kept),
        "wrong_removed": sum(r.wrong for r in reids if r.removed),
    }
