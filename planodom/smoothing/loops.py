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

Verification (``loop_verify``, :meth:`LoopClosingBuilder._verify`): a match places epoch
k in the map; that is a correction of the chained guess. It must agree with the last
accepted correction (chi2 on yaw, x, y under the match's and the chained odometry's
covariance since then), else it ties nothing; a new correction (the first, or after a
refusal) needs ``loop_confirmations`` successive agreeing matches. "tracked" also matches
around the corrected prediction with bounds grown from the accepted correction's epoch.
With ``loop_refuse_misfit`` a rotation-only match (verified on its yaw alone) is also
refused when a tied wall's offset residual at its own pose exceeds chi2(1) at
``loop_gate_quantile`` under the drift along the wall's normal plus both planes' offset
variances, or when two ties of parallel walls disagree on the pose along their normal
(:mod:`planodom.smoothing.match_fit`). With ``loop_refuse_ambiguous`` a tie is refused when
swapped for a parallel old wall it explains the match about as well (a likelihood ratio).

After optimisation (:func:`planodom.smoothing.loop_records.gate_reidentifications`) a
match one of whose re-identified factors has a squared whitened error above the
``loop_gate_quantile`` of chi2(3), or of the tracked plane factors' own errors when larger
(the plane covariances are too small on continuous-motion data: a fixed chi2 gate removed
half the right ties), is removed whole and the graph solved again from the initial
values. On simulated data each re-identification is checked against the planes' true
surface ids (``truth_id``): :class:`Reidentification`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from planodom.config import PlanodomConfig
from planodom.geometry import Plane, PlaneSupport, invert_transform, pose5_from_transform
from planodom.odometry import RelativePose, Status, estimate_relative_pose
from planodom.odometry.twist_sigma import chi2_quantile
from planodom.smoothing.graph import GraphBuilder, GraphUpdate
from planodom.smoothing.loop_records import LoopMatch, Reidentification
from planodom.smoothing.match_fit import (
    _extent,
    _sphere_union,
    non_parallel,
    offset_residuals,
    offset_verdict,
    tie_ambiguities,
)

#: A landmark whose world normal has at least this |z| is ground-like (context).
GROUND_COS = 0.9
#: Only walls (|z| of the normal at most this) are re-identified: they observe the
#: horizontal position and yaw, what the 5-DoF odometry lets drift (0.5, admitting
#: inclined roofs, pulled the height of a lidar lap 4 m off and cost 0.08 m of ATE on
#: the 2D-rig world 2).
WALL_SIN = 0.2
#: Candidates closer than these (normals, offsets) are one plane seen by two tracks.
DUPLICATE_COS, DUPLICATE_OFFSET_M = float(np.cos(np.radians(3.0))), 0.2
#: Largest rotation bound of a re-identification, degrees.
MAX_ROTATION_BOUND_DEG = 45.0
Spans = list[tuple[int, int]]  # (epoch, epoch) pairs of the chained odometry


def _mahalanobis(T: np.ndarray, dofs: list[int], cov: np.ndarray) -> float:
    """Squared Mahalanobis norm of entries ``dofs`` of ``T``'s (roll, pitch, yaw, x, y)."""
    v = pose5_from_transform(T)[dofs]
    return float(v @ np.linalg.solve(cov, v))


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
        self.matches: list[LoopMatch] = []
        #: (4, 4) world-frame correction of the chained guess by the last accepted match:
        #: the map places epoch k at ``correction @ poses[k]`` (identity before the first).
        self.correction = np.eye(4)
        self._reference: tuple[int, int] | None = None  # (k, map epoch) of the correction
        self._pending: list[tuple[int, int, np.ndarray]] = []  # agreeing, unconfirmed
        self.attempts = 0
        self.travelled: list[float] = []
        self.variances: list[tuple[float, float]] = []  # chained (xy, yaw) variance sums
        self._stated: list[np.ndarray] = []  # the same per axis, as stated (_prior_sigma)
        self._extents: dict[int, tuple[int, np.ndarray, float]] = {}  # j -> (epoch, c, r)
        #: j -> (last-seen epoch, world plane with its extent), see _map_plane
        self._world_planes: dict[int, tuple[int, Plane]] = {}
        self._rows: dict[int, int] = {}  # landmark id -> row of the map arrays (_map)
        self._ids, self._seen = np.zeros(0, int), np.zeros(0, int)
        self._nz, self._radii, self._centres = np.zeros(0), np.zeros(0), np.zeros((0, 3))

    def _extent_of(self, j: int) -> tuple[np.ndarray, float]:
        """World centroid and radius of a sphere holding every accepted observation's
        support of landmark j (merged in as they come, checked once per epoch)."""
        lm = self.landmarks[j]
        assert lm.last_seen is not None
        e = lm.last_seen[0]
        cached = self._extents.get(j)
        if cached is not None and cached[0] == e:
            return cached[1], cached[2]
        c, r = _extent(self.planes[e][lm.last_index], self.poses[e])
        if cached is not None:
            c, r = _sphere_union(cached[1], cached[2], c, r)
        self._extents[j] = (e, c, r)
        return c, r

    def _map(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The map's landmarks with an accepted observation, as arrays (refreshed where a
        landmark was seen since): ids (L,), extent centres (L, 3) m, radii (L,) m, |z| of
        the world normals (L,), last-seen epochs (L,). Arrays, not a loop per landmark and
        epoch: a lidar lap holds thousands of landmarks (2 500 on a 32-beam lap)."""
        rows = self._rows
        for j, lm in self.landmarks.items():
            if lm.last_seen is None:
                continue
            row = rows.get(j)
            if row is not None and self._seen[row] == lm.last_seen[0]:
                continue
            if row is None:
                row = rows[j] = len(rows)
                if row == len(self._seen):  # grow the arrays (amortised doubling)
                    self._ids, self._seen, self._nz, self._radii = (
                        np.resize(a, 2 * len(a) + 16)
                        for a in (self._ids, self._seen, self._nz, self._radii)
                    )
                    self._centres = np.resize(self._centres, (2 * len(self._centres) + 16, 3))
            centre, radius = self._extent_of(j)
            self._ids[row], self._seen[row], self._nz[row] = j, lm.last_seen[0], 0.0
            self._centres[row], self._radii[row] = centre, radius
            self._nz[row] = abs(lm.plane_world[2])
        n = len(rows)
        return self._ids[:n], self._centres[:n], self._radii[:n], self._nz[:n], self._seen[:n]

    def _candidates(self, k: int) -> tuple[list[int], int | None]:
        """Landmarks unseen for the minimum gap whose support is near the predicted pose,
        but ground-like ones, and the most recently seen near ground-like landmark
        (context: it gives the walls' dihedral angles a horizontal partner; never tied:
        tying old ground pieces, tilted by their few observations, raised the ATE from
        0.08 to 0.20 m on the issue world)."""
        c, position = self.config, self.poses[k][:3, 3]
        ids, centres, radii, nz, seen = self._map()
        gap = np.linalg.norm(centres - position, axis=1) - radii
        near = gap <= c.loop_radius_m
        ground, walls = near & (nz >= GROUND_COS), near & (nz <= WALL_SIN)
        walls &= seen <= k - c.loop_min_gap_epochs
        context = None
        if ground.any():  # the latest seen (the first of them on ties)
            rows = np.flatnonzero(ground)
            context = int(ids[rows[np.argmax(seen[rows])]])
        out = self._distinct(sorted(int(j) for j in ids[walls]))
        if len(out) > c.loop_max_candidates:  # the nearest ones
            by_id = dict(zip(ids[walls].tolist(), gap[walls].tolist(), strict=True))
            out = sorted(sorted(out, key=lambda j: (by_id[j], j))[: c.loop_max_candidates])
        return out, context

    def _distinct(self, candidates: list[int]) -> list[int]:
        """One landmark per physical plane: of candidates within 3 deg and 0.2 m of each
        other (a track broken in two), the one with the largest extent."""
        ordered = sorted(candidates, key=lambda j: (-self._extents[j][2], j))
        kept: list[int] = []
        for j in ordered:
            p = self.landmarks[j].plane_world
            if not any(
                self.landmarks[q].plane_world[:3] @ p[:3] > DUPLICATE_COS
                and abs(self.landmarks[q].plane_world[3] - p[3]) < DUPLICATE_OFFSET_M
                for q in kept
            ):
                kept.append(j)
        return sorted(kept)

    def _map_plane(self, j: int, T_pred_world: np.ndarray) -> Plane:
        """Landmark j's last accepted observation in the predicted frame, its support
        replaced by the landmark's whole extent."""
        lm = self.landmarks[j]
        assert lm.last_seen is not None
        e, coefficients = lm.last_seen
        cached = self._world_planes.get(j)
        if cached is not None and cached[0] == e:  # unchanged since its last sighting
            return cached[1].transformed(T_pred_world)
        plane = self.planes[e][lm.last_index]
        if plane.normal @ coefficients[:3] < 0:
            plane = plane.flipped()
        world = plane.transformed(self.poses[e])
        centre, radius = self._extent_of(j)
        centre = centre - (world.normal @ centre + world.offset) * world.normal
        u = np.cross(world.normal, [0.0, 0.0, 1.0] if abs(world.normal[2]) < 0.9 else [1.0, 0, 0])
        u /= np.linalg.norm(u)
        v = np.cross(world.normal, u)
        polygon = centre + radius * np.array([u, v, -u, -v])
        n_points = world.support.n_points if world.support is not None else 0
        world = replace(world, support=PlaneSupport(centre, polygon, n_points))
        self._world_planes[j] = (e, world)
        return world.transformed(T_pred_world)

    def add_epoch(
        self, planes: Sequence[Plane], relatives: Sequence[RelativePose] = (), min_epoch: int = 0
    ) -> GraphUpdate:
        """:meth:`GraphBuilder.add_epoch`, noting the variances of the step into the epoch."""
        k, c = self.n_epochs, self.config
        var_t, var_r = c.fallback_translation_sigma_m**2, c.fallback_rotation_sigma_rad**2
        for r in relatives:
            if r.curr == k and r.delta == 1 and r.translation_observed and r.covariance is not None:
                cov = np.asarray(r.covariance, dtype=float).reshape(5, 5)
                var_t, var_r = float(cov[3, 3] + cov[4, 4]), float(cov[2, 2])
        last_t, last_r = self.variances[-1] if self.variances else (0.0, 0.0)
        self.variances.append((last_t + var_t if k else 0.0, last_r + var_r if k else 0.0))
        # the same as the odometry states it (_prior_sigma): per axis, the fallback factor's
        # sigma on each axis, the yaw of a rotation-only epoch as measured
        var_a, var_y = c.fallback_translation_sigma_m**2, c.fallback_rotation_sigma_rad**2
        for r in relatives:
            if r.curr == k and r.delta == 1 and r.measured and r.covariance is not None:
                cov = np.asarray(r.covariance, dtype=float).reshape(5, 5)
                var_y = float(cov[2, 2])
                var_a = float(cov[3, 3] + cov[4, 4]) / 2 if r.translation_observed else var_a
        last = self._stated[-1] if k else np.zeros(2)
        self._stated.append(last + (var_a, var_y) if k else last)
        return super().add_epoch(planes, relatives, min_epoch)

    def _chain(self, spans: Spans) -> tuple[float, float, float]:
        """Distance driven (m) and summed translation and yaw variances (m^2, rad^2) of
        the chained odometry over epoch ``spans`` ((a, b) pairs, in any order)."""
        distance = var_t = var_r = 0.0
        for a, b in spans:
            a, b = min(a, b), max(a, b)
            distance += self.travelled[b] - self.travelled[a]
            var_t += self.variances[b][0] - self.variances[a][0]
            var_r += self.variances[b][1] - self.variances[a][1]
        return distance, var_t, var_r

    def _drift_covariance(
        self, spans: Spans, stated: bool = False, run: bool = False
    ) -> np.ndarray:
        """(3, 3) covariance of the chained guess's (yaw, x, y) drift over ``spans``: the
        odometry's variances (``stated``: as it states them, ``run``: the run's where kept,
        see :meth:`_prior_sigma`), the yaw's lever arm, and the minimum bounds' floors."""
        c = self.config
        distance, var_t, var_r = self._chain(spans)
        var_t *= 0.5
        if stated:
            var_t, var_r = np.sum([abs(self._stated[b] - self._stated[a]) for a, b in spans], 0)
        var_xy = var_t + var_r * distance**2 + (c.loop_min_translation_m / c.loop_sigmas) ** 2
        floor_r = np.radians(self.full_config.association.prior_rotation_deg) / c.loop_sigmas
        return np.diag([var_r + floor_r**2, var_xy, var_xy])

    def _match_config(self, spans: Spans) -> PlanodomConfig:
        """Association bounds around the prediction: ``loop_sigmas`` standard deviations of
        the chained odometry over ``spans`` (from the candidates' last sighting to k, or
        from the accepted correction's epochs, see :meth:`_reidentify`; translation, and
        rotation times the distance driven), at most the drift fraction of that distance;
        plus the minima."""
        c, a = self.config, self.full_config.association
        distance, var_t, var_r = self._chain(spans)
        sigma_t, sigma_r = np.sqrt(var_t), np.sqrt(var_r)
        grown = c.loop_sigmas * (sigma_t + sigma_r * distance)
        translation = c.loop_min_translation_m + min(grown, c.loop_drift_fraction * distance)
        rotation_deg = c.loop_sigmas * np.degrees(sigma_r)
        rotation = min(
            a.prior_rotation_deg + min(rotation_deg, c.loop_rotation_deg_per_m * distance),
            MAX_ROTATION_BOUND_DEG,
        )
        changes = {
            "association.prior_translation_m": translation,
            "association.prior_rotation_deg": rotation,
            "odometry.retry_without_prior": False,
            # The refinement measures a direction when its sigma is at most this: the
            # odometry's few centimetres (one epoch's motion) refused every match of the
            # synthetic loop (3 cm planes) as rotation only; a match that narrows the
            # bounds' sigma (translation / loop_sigmas) measures the loop.
            "odometry.refine_max_sigma_m": max(
                self.full_config.odometry.refine_max_sigma_m, translation / c.loop_sigmas
            ),
        }
        return self.full_config.updated_fields(changes, source="loop closure bounds")

    def _reidentify(self, update: GraphUpdate) -> None:
        k, c = update.epoch, self.config
        step = 0.0 if k == 0 else np.linalg.norm(self.poses[k][:2, 3] - self.poses[k - 1][:2, 3])
        self.travelled.append((self.travelled[-1] if self.travelled else 0.0) + float(step))
        curr = self.planes[k]
        if not c.loop_closure or len(curr) < c.loop_min_matches or k % c.loop_every_epochs:
            return
        candidates, ground = self._candidates(k)
        if len(candidates) < c.loop_min_matches - 1:
            return
        self.attempts += 1
        ref = self._reference if c.loop_verify == "tracked" else None
        T_world_pred = self.poses[k] if ref is None else self.correction @ self.poses[k]
        T_pred_world = invert_transform(T_world_pred)
        oldest = min(self.landmarks[j].last_seen[0] for j in candidates)  # type: ignore[index]
        # tracked: the drift since the accepted correction and between the map parts
        cfg = self._match_config([(oldest, k)] if ref is None else [(ref[0], k), (ref[1], oldest)])
        context = [] if ground is None else [ground]
        map_planes = [self._map_plane(j, T_pred_world) for j in candidates + context]
        rel = estimate_relative_pose(map_planes, curr, cfg, prior=np.eye(4))
        pairs = np.asarray(rel.associations, dtype=int).reshape(-1, 2)
        old = pairs[pairs[:, 0] < len(candidates)]
        full = rel.status is Status.OK and len(pairs) >= c.loop_min_matches and len(old) >= 2
        rotation = rel.status is Status.DEGENERATE and c.loop_accept_degenerate and len(old) >= 1
        normals = (
            np.stack([curr[i].normal for i in pairs[:, 1]]) if len(pairs) else np.zeros((0, 3))
        )
        if not (full or rotation) or not non_parallel(normals):
            return
        T = np.asarray(rel.T_prev_curr, dtype=float)
        cov = np.asarray(rel.covariance if rel.covariance is not None else np.eye(5), float)
        match = LoopMatch(k, oldest, T_world_pred, T, cov.reshape(5, 5), np.zeros((3, 3)), np.nan,
                          [(candidates[m], int(i)) for m, i in old])  # fmt: skip
        self.matches.append(match)
        sigma, angle = c.default_plane_offset_sigma_m, cfg.association.strict_normal_deg
        walls = map_planes[: len(candidates)]
        if c.loop_refuse_ambiguous != "off":  # at the predicted position (match_fit)
            T_pred = T.copy()
            T_pred[:2, 3] = 0.0
            fit = offset_residuals(walls, curr, old, T_pred, sigma, angle, np.zeros((0, 0)))
            limit = chi2_quantile(c.loop_gate_quantile, 1)
            prior = self._prior_sigma(k, oldest, match.ties)
            mode = c.loop_refuse_ambiguous  # "run": as "parts", no "same wall" exclusion
            same = (self._map_drift(candidates), 0.0 if mode == "run" else limit)
            rows = tie_ambiguities(fit, prior, sigma, same, mode in ("parts", "run"))
            match.ambiguity = float(np.min(rows, initial=np.inf))
            if match.ambiguity <= limit:  # its pose rests on an alias: ties the clear walls
                old, full, T = old[rows > limit], False, T_pred  # verified as rotation-only
                match.ties = [(candidates[m], int(i)) for m, i in old]
                if not len(old):
                    match.verdict = "ambiguous"
                    return
        if c.loop_refuse_misfit and not full:
            # the map's walls agree to the bounds' floor (the chain's drift between their
            # sightings, yaw's lever arm over the whole route, let world 2's 4.7 m pass)
            var = np.full((len(old), len(old)), self._drift_covariance([])[1, 1])
            match.offsets = offset_residuals(walls, curr, old, T, sigma, angle, var)
        if c.loop_verify != "off":
            match.verdict = self._verify(match, T_world_pred @ T, full)
        if match.verdict != "accepted":
            return
        for m, i in old:
            self._tie(update, candidates[m], int(i), map_planes[m].normal @ T[:3, :3])

    def _prior_sigma(self, k: int, oldest: int, ties: list[tuple[int, int]]) -> float:
        """Sigma (m, per axis) of the predicted position in the map since the accepted
        correction and between the map parts (tracked), else since the candidates' last
        sighting (:meth:`_drift_covariance`; ``loop_refuse_ambiguous`` "stated", "run"), not
        the association bounds (capped, metres too tight: 2D-rig world 16 at 2 cm)."""
        ref = self._reference if self.config.loop_verify == "tracked" else None
        spans = [(oldest, k)]
        if ref is not None:
            seen = min(self.landmarks[j].last_seen[0] for j, _ in ties)  # type: ignore[index]
            spans = [(ref[0], k), (ref[1], seen)]
        mode = self.config.loop_refuse_ambiguous
        return float(np.sqrt(self._drift_covariance(spans, mode == "stated", mode == "run")[1, 1]))

    def _map_drift(self, landmarks: list[int]) -> np.ndarray:
        """(N, N) per-axis variance (m^2) of the map's drift between the last sightings of
        ``landmarks``, as the odometry states it (see :meth:`_prior_sigma`)."""
        seen = np.array([self.landmarks[j].last_seen[0] for j in landmarks])  # type: ignore[index]
        stated, travelled = np.asarray(self._stated), np.asarray(self.travelled)
        lo, hi = np.minimum.outer(seen, seen), np.maximum.outer(seen, seen)
        var_a, var_y = (stated[hi] - stated[lo]).transpose(2, 0, 1)
        return var_a + var_y * (travelled[hi] - travelled[lo]) ** 2

    def _verify(self, match: LoopMatch, T_world_curr: np.ndarray, full: bool) -> str:
        """Whether the correction a match implies (``T_world_curr``: epoch k as the map
        places it) agrees with the accepted correction within the drift since it was
        taken and between the parts of the map they matched (the earliest last sighting
        of their tied landmarks); else whether ``loop_confirmations`` successive matches
        agree on a new one. Returns "accepted" or why it is refused."""
        c, k = self.config, match.epoch
        seen = min(self.landmarks[j].last_seen[0] for j, _ in match.ties)  # type: ignore[index]
        W = T_world_curr @ invert_transform(self.poses[k])
        limit = chi2_quantile(c.loop_gate_quantile, 3 if full else 1)
        if self._reference is not None:
            k_ref, seen_ref = self._reference
            match.drift = self._drift_covariance([(k_ref, k), (seen_ref, seen)])
            match.mahalanobis = self._disagreement(match, self.correction, T_world_curr, full)
            if match.offsets is not None and match.mahalanobis <= limit:
                drift_xy = match.drift[1:, 1:]  # isotropic: the same in the predicted frame
                verdict, match.misfit = offset_verdict(match.offsets, drift_xy, limit)
                if verdict:
                    return verdict
            if match.mahalanobis <= limit:
                if full:
                    self.correction, self._reference = W, (k, seen)
                self._pending.clear()
                return "accepted"
        if not full:
            return "rotation only, unverified"
        if self._pending:
            k_p, seen_p, W_p = self._pending[-1]
            match.drift = self._drift_covariance([(k_p, k), (seen_p, seen)])
            if self._disagreement(match, W_p, T_world_curr, full) > limit:
                self._pending.clear()
        self._pending.append((k, seen, W))
        if len(self._pending) < c.loop_confirmations:
            return "awaiting confirmation" if self._reference is None else "inconsistent"
        self.correction, self._reference = W, (k, seen)
        self._pending.clear()
        return "accepted"

    def _disagreement(
        self, match: LoopMatch, W: np.ndarray, T_world_curr: np.ndarray, full: bool
    ) -> float:
        """Squared Mahalanobis distance between epoch k as the map places it and as the
        correction ``W`` (4, 4) of the chained guess does, over (yaw, x, y) (yaw only for
        a rotation-only match), under the match's covariance plus ``match.drift``."""
        dofs = [2, 3, 4] if full else [2]
        cov = np.zeros((5, 5))
        cov[2:, 2:] = match.drift
        cov = cov[np.ix_(dofs, dofs)] + match.covariance[np.ix_(dofs, dofs)]
        T = invert_transform(W @ self.poses[match.epoch]) @ T_world_curr
        return _mahalanobis(T, dofs, cov)

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
