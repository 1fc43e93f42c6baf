"""Building the factor graph epoch by epoch, for the batch and the fixed-lag smoother alike.

Variables: ``X(k)`` the pose ``T_world_base`` of epoch k (Pose3), ``L(j)`` plane landmark j
(OrientedPlane3, in the world frame or in its anchor frame), ``A(j)`` the anchor frame of
an anchored landmark (Pose3, see :mod:`factors.planes`), ``F(k)`` epoch k's deskewed frame
(Pose3, the one its plane factors are on; ``smoothing.deskew_noise`` "twist_change_frame*").

Factors per epoch k:

- a 5-DoF between factor (:func:`factors.pose5.pose5_factor`) for every resolved relative
  pose from epoch ``k - delta``, ``delta = 1..D``, noise the odometry's covariance (floored,
  plus the deskewing error, :mod:`.deskew_noise`), optional robust kernel; with
  ``between_factors`` "untracked" (default) only for those whose source planes are not
  plane factors of shared landmarks already (:meth:`GraphBuilder.in_plane_factors`): both
  would count the same measurements twice;
- a weak vertical factor between ``X(k-1)`` and ``X(k)`` (no vertical jumps);
- a plane factor for every observation of a tracked plane (:mod:`.landmarks`) once its track
  spans ``min_landmark_epochs`` epochs, noise its fit covariance in OrientedPlane3 tangent
  coordinates plus floors and deskewing error (see :mod:`.noise`); a prior on ``X(0)``; a
  weak fallback between factor (the odometry's prediction, else constant velocity) for an
  epoch no resolved relative pose reaches (graph connected).

Gauge and observability. The first-pose prior fixes the 6-DoF gauge; anchor priors fix
the anchors' (pure gauge) freedom. The 5-DoF factors observe relative roll, pitch, yaw
and horizontal translation, never z. A plane factor observes the pose's offset along the
plane's normal, so vertical walls observe only horizontal position, while ground, ceiling
and inclined planes seen from two epochs observe the change of height between them. With
walls only, every pose's z would be free (a singular system); the weak vertical factor
(``vertical_sigma_m`` per epoch, a random walk in height) removes that null space and is
outweighed wherever a non-vertical plane observes z.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial

import gtsam
import numpy as np

from planodom.config import SmoothingConfig
from planodom.geometry import Plane, transform_planes
from planodom.odometry.relative import RelativePose
from planodom.smoothing.deskew_noise import between_keys, deskew_from_config
from planodom.smoothing.landmarks import LandmarkTracker
from planodom.smoothing.motion import FALLBACK_STEPS, medoid_transform
from planodom.smoothing.noise import between_covariance, plane_factor_covariance, with_robust_kernel
from planodom_factors.planes import (
    anchor_pose,
    anchor_prior,
    anchored_plane_factor,
    orient_measurement,
    plane_factor,
    plane_noise,
    predict_plane,
)
from planodom_factors.pose5 import pose5_factor, rotation_factor, vertical_factor

X = gtsam.symbol_shorthand.X
L = gtsam.symbol_shorthand.L
A = gtsam.symbol_shorthand.A
F = gtsam.symbol_shorthand.F  # an epoch's deskewed frame (smoothing.deskew_noise "..._frame")


@dataclass
class GraphUpdate:
    """What one epoch adds: new factors, initial values of new variables, key timestamps;
    ``gaussian`` maps the index (in ``factors``) of each robust factor to its Gaussian twin
    (``batch.covariance_graph``); ``fallback`` the fallback factors' indices; ``planes``
    each plane factor's epoch and oriented measured plane (:mod:`.sandwich`)."""

    epoch: int
    factors: gtsam.NonlinearFactorGraph
    values: gtsam.Values
    timestamps: dict[int, float]
    gaussian: dict[int, gtsam.NonlinearFactor] = field(default_factory=dict)
    fallback: list[int] = field(default_factory=list)
    planes: dict[int, tuple[int, Plane]] = field(default_factory=dict)


@dataclass
class GraphStats:
    """Counts of what went into the graph: ``between`` the relative poses that became
    factors, ``between_left_out`` the resolved ones ``SmoothingConfig.between_factors``
    left out (their source planes are plane factors already, or "none")."""

    between: int = 0
    between_left_out: int = 0
    fallback: int = 0
    vertical: int = 0
    plane_factors: int = 0
    global_landmarks: int = 0
    anchored_landmarks: int = 0
    flipped: int = 0
    rejected_flips: int = 0
    gated: int = 0
    reidentified: int = 0  # loop closure: ties to old landmarks, and those the gate refused
    reidentified_removed: int = 0
    dropped_observations: int = 0
    unresolved_epochs: list[int] = field(default_factory=list)


@dataclass
class _Landmark:
    key: int
    anchor_key: int | None
    T_world_anchor: np.ndarray | None
    plane_world: np.ndarray  # (4,) current estimate, world frame
    last_epoch: int  # latest epoch whose update touched the landmark (its timestamp)
    last_seen: tuple[int, np.ndarray] | None = None  # last accepted (epoch, (4,) base frame)
    last_index: int = -1  # plane index of that observation


def plane_from_anchor(T_world_anchor: np.ndarray, plane_anchor: np.ndarray) -> np.ndarray:
    """(4,) world plane from a plane (4,) given in the anchor frame ``T_world_anchor``."""
    n, d = transform_planes(T_world_anchor, plane_anchor[None, :3], plane_anchor[3:])
    return np.append(n[0], d[0])


class GraphBuilder:
    """Turns epochs of planes and relative poses into factors, values and timestamps.

    One instance per sequence; call :meth:`add_epoch` for epochs 0, 1, 2, ... in order.
    ``poses`` holds the current estimate of each pose (the chained initial guess, or the
    smoother's estimate after :meth:`update_estimates`); it seeds new variables.
    """

    def __init__(self, config: SmoothingConfig, T_world_first: np.ndarray | None = None) -> None:
        self.config = config
        self.tracker = LandmarkTracker(config.min_landmark_epochs)
        self.poses: dict[int, np.ndarray] = {}
        self.planes: dict[int, Sequence[Plane]] = {}
        self.landmarks: dict[int, _Landmark] = {}
        self.stats = GraphStats()
        self.n_epochs = 0
        self._T_world_first = np.eye(4) if T_world_first is None else np.asarray(T_world_first)
        self.initial_poses: np.ndarray | None = None  # (E, 4, 4) overrides the chained guess
        self._robust_planes = config.robust_planes and config.robust_kernel != "none"
        self._last_step: np.ndarray | None = None
        self._steps: list[np.ndarray] = []  # the last FALLBACK_STEPS measured steps
        self.first_step: np.ndarray | None = None  # fallback before any measured step
        self._factor_landmark: dict[tuple[int, int], int] = {}  # (epoch, plane) -> landmark
        self._update = GraphUpdate(-1, gtsam.NonlinearFactorGraph(), gtsam.Values(), {})
        self.reidentified: dict[tuple[int, int], int] = {}  # (epoch, plane) -> old landmark
        self.deskew = deskew_from_config(config.deskew_noise)
        self.plane_share: np.ndarray | None = None  # sandwich_plane_share: (E, 6, 6)

    def _initial_pose(self, k: int, resolved: list[RelativePose]) -> np.ndarray | None:
        """Chained guess of ``T_world_k`` from the resolved relative poses, or None.

        Each full (5-DoF) relative pose chained from its earlier epoch is a candidate; with
        three or more the medoid (least summed distance, metres plus radians times 10 m) is
        taken, so that one outlier relative pose cannot throw the guess off; else the
        smallest delta. Rotation-only relative poses are used only when nothing else is.
        """
        known = [r for r in resolved if r.prev in self.poses]
        full = sorted((r for r in known if r.translation_observed), key=lambda r: r.delta)
        pool = full or sorted(known, key=lambda r: r.delta)
        if not pool:
            return None
        candidates = [self.poses[r.prev] @ np.asarray(r.T_prev_curr, dtype=float) for r in pool]
        if len(candidates) < 3:
            return candidates[0]
        return medoid_transform(candidates)

    def _fallback_motion(self, bridge: RelativePose | None) -> np.ndarray:
        """(4, 4) mean ``T_{k-1}_k`` of the fallback into an epoch nothing measured: the
        odometry's unresolved delta = 1 result ``bridge`` (its prediction; world 6 in a turn:
        0.1-0.8 deg off, the last step 1-2 deg), else the last measured step repeated, else
        ``first_step`` (``smoothing.fallback_start``), else identity; never the estimates."""
        if bridge is not None:
            return np.asarray(bridge.T_prev_curr, dtype=float)
        if self.config.fallback_step == "medoid" and len(self._steps) >= 3:
            return medoid_transform(self._steps)
        return next((s for s in (self._last_step, self.first_step) if s is not None), np.eye(4))

    def add_epoch(
        self,
        planes: Sequence[Plane],
        relatives: Sequence[RelativePose] = (),
        min_epoch: int = 0,
    ) -> GraphUpdate:
        """Add the next epoch.

        Args:
            planes: the epoch's measured planes (base frame, normals towards the sensor).
            relatives: relative poses from earlier epochs to this one (``curr`` must be
                this epoch); pairs with ``delta > delta_max`` or ``prev < min_epoch`` are
                skipped.
            min_epoch: oldest epoch still in the graph (fixed-lag smoothing); factors on
                older poses are not built.

        Returns:
            The factors, values and timestamps (epoch index) this epoch adds.
        """
        k = self.n_epochs
        self.n_epochs += 1
        self.planes[k] = planes
        update = GraphUpdate(k, gtsam.NonlinearFactorGraph(), gtsam.Values(), {})
        self._update = update  # its Gaussian twins and plane factors are recorded there
        usable = [
            r
            for r in relatives
            if r.curr == k and min_epoch <= r.prev < k and r.delta <= self.config.delta_max
        ]
        measured = [r for r in usable if r.measured]
        for rel in measured if self.deskew is not None else ():
            self.deskew.add(rel)  # type: ignore[union-attr]  # before this epoch's factors
        self._add_pose(usable, min_epoch, update)
        self._reidentify(update)
        associations = {r.delta: r.associations for r in usable}  # (tracked even unmeasured)
        roots = self.tracker.add_epoch(k, len(planes), associations)
        for root in dict.fromkeys(roots):  # unique, in plane order
            j = self.tracker.landmark(root)
            if j is not None:
                self._add_observations(j, root, min_epoch, update)
        # Between factors last: whether a relative pose's planes are already plane
        # factors is known once this epoch's observations are in.
        self._add_between_factors(measured, update)
        return update

    def _add_pose(self, usable: list[RelativePose], min_epoch: int, update: GraphUpdate) -> None:
        """The pose variable of epoch ``update.epoch`` with its initial guess, and its
        prior (first epoch) or its fallback and vertical factors."""
        c, k, graph = self.config, update.epoch, update.factors
        measured = [r for r in usable if r.measured]
        bridge = next((r for r in usable if r.delta == 1 and not r.measured), None)
        if k == 0:
            T = self._T_world_first
            noise = gtsam.noiseModel.Diagonal.Sigmas(np.full(6, c.prior_sigma))
            graph.add(gtsam.PriorFactorPose3(X(0), gtsam.Pose3(T), noise))
        else:
            guess = self._initial_pose(k, measured)
            T_rel = self._fallback_motion(bridge)
            if guess is None:
                self.stats.unresolved_epochs.append(k)
            T = self.poses[k - 1] @ T_rel if guess is None else guess
            T = T if self.initial_poses is None else self.initial_poses[k]
            if not any(r.translation_observed for r in measured) and k - 1 >= min_epoch:
                # Nothing measured the horizontal translation into epoch k (unresolved or
                # rotation-only): a weak constant-velocity factor keeps the graph connected.
                sigmas = np.array(
                    [c.fallback_rotation_sigma_rad] * 3 + [c.fallback_translation_sigma_m] * 2
                )
                noise = gtsam.noiseModel.Diagonal.Sigmas(sigmas)
                update.fallback.append(graph.size())
                graph.add(pose5_factor(X(k - 1), X(k), T_rel, noise))
                self.stats.fallback += 1
            if k - 1 >= min_epoch:
                noise = gtsam.noiseModel.Isotropic.Sigma(1, c.vertical_sigma_m)
                graph.add(vertical_factor(X(k - 1), X(k), 0.0, noise))
                self.stats.vertical += 1
        self.poses[k] = T
        update.values.insert(X(k), gtsam.Pose3(T))
        update.timestamps[X(k)] = float(k)
        if self.deskew is not None:  # its deskewed frame F(k), with "..._frame"
            self.deskew.add_frame(k, X(k), F(k), T, update)

    def _reidentify(self, update: GraphUpdate) -> None:
        """Hook: ties to old landmarks (:class:`.loops.LoopClosingBuilder`)."""

    def _add_between_factors(self, measured: list[RelativePose], update: GraphUpdate) -> None:
        """A 5-DoF (or rotation-only) factor per measured relative pose into this epoch,
        unless ``between_factors`` leaves it out (see :meth:`in_plane_factors`)."""
        c, k = self.config, update.epoch
        robust = c.robust_between and c.robust_kernel != "none"
        for rel in measured:
            if rel.delta == 1 and rel.translation_observed:
                self._last_step = np.asarray(rel.T_prev_curr, dtype=float)
                self._steps = [*self._steps[1 - FALLBACK_STEPS :], self._last_step]
            if c.between_factors == "none" or (
                c.between_factors == "untracked" and self.in_plane_factors(rel)
            ):
                self.stats.between_left_out += 1
                continue
            make = pose5_factor if rel.translation_observed else rotation_factor
            keys, deskew = between_keys(self.deskew, rel.prev, k, X, F)
            base = gtsam.noiseModel.Gaussian.Covariance(between_covariance(rel, c, deskew))
            factor = partial(make, *keys, rel.T_prev_curr)
            self._add(update.factors, factor, base, robust)
            self.stats.between += 1

    def _add(
        self,
        graph: gtsam.NonlinearFactorGraph,
        make: Callable[[gtsam.noiseModel.Base], gtsam.NonlinearFactor],
        base: gtsam.noiseModel.Gaussian,
        robust: bool,
    ) -> None:
        """Add the factor ``make(noise)``: ``base`` wrapped in the robust kernel when ``robust``
        (its Gaussian twin ``make(base)`` kept under its index, :class:`GraphUpdate`)."""
        if robust:
            self._update.gaussian[graph.size()] = make(base)
        graph.add(make(with_robust_kernel(base, self.config) if robust else base))

    def in_plane_factors(self, rel: RelativePose) -> bool:
        """Whether the planes a relative pose was computed from are plane factors already.

        True when ``rel.sources`` is known and non-empty and each source association
        ``(i, j)`` has a plane factor for plane i of epoch ``prev`` and for plane j of
        epoch ``curr`` on one and the same landmark: the relative pose is then a function
        of measurements the graph holds, and a factor for it would count them twice.
        """
        if rel.sources is None or len(rel.sources) == 0:
            return False
        seen = self._factor_landmark
        for i, j in np.asarray(rel.sources, dtype=int).reshape(-1, 2):
            lm = seen.get((rel.prev, int(i)))
            if lm is None or seen.get((rel.curr, int(j))) != lm:
                return False
        return True

    def _new_landmark(
        self,
        j: int,
        epoch: int,
        index: int,
        graph: gtsam.NonlinearFactorGraph,
        values: gtsam.Values,
    ) -> _Landmark:
        c = self.config
        T = self.poses[epoch]
        world = self.planes[epoch][index].transformed(T).coefficients
        origin = T[:3, 3]
        use_global = c.plane_factor == "global" or (
            c.plane_factor == "auto"
            and not self._robust_planes
            and float(np.linalg.norm(origin)) < c.global_plane_max_distance_m
        )
        if use_global:
            values.insert(L(j), gtsam.OrientedPlane3(world))
            self.stats.global_landmarks += 1
            return _Landmark(L(j), None, None, world, epoch)
        T_wa = anchor_pose(origin)
        values.insert(A(j), gtsam.Pose3(T_wa))
        values.insert(L(j), gtsam.OrientedPlane3(predict_plane(T_wa, world)))
        # the anchor's prior is pure gauge: its scale from the fit, not the deskewing's
        cov = plane_factor_covariance(self.planes[epoch][index], c, self.deskew, epoch, False)
        sigma_n, sigma_d = np.sqrt(max(cov[0, 0], cov[1, 1])), np.sqrt(cov[2, 2])
        noise = gtsam.noiseModel.Diagonal.Sigmas(np.array([sigma_n] * 3 + [sigma_d] * 3))
        graph.add(anchor_prior(A(j), T_wa, noise))
        self.stats.anchored_landmarks += 1
        return _Landmark(L(j), A(j), T_wa, world, epoch)

    def _add_observations(self, j: int, root: int, min_epoch: int, update: GraphUpdate) -> None:
        """Plane factors for the pending observations of landmark ``j`` (track ``root``),
        creating the landmark once its track spans ``min_landmark_epochs`` epochs."""
        graph, k = update.factors, update.epoch
        usable = []
        for e, i in self.tracker.take_pending(root):
            if (e, i) in self.reidentified:  # a factor on an older landmark already
                continue
            if e < min_epoch or e not in self.poses:
                self.stats.dropped_observations += 1
            else:
                usable.append((e, i))
        lm = self.landmarks.get(j)
        if lm is None and len({e for e, _ in usable}) < self.config.min_landmark_epochs:
            self.tracker.put_back(root, usable)  # wait for more observations in the window
            return
        if lm is not None and lm.last_epoch < min_epoch:
            # The landmark has left the window; its key is gone from the smoother.
            self.stats.dropped_observations += len(usable)
            return
        if lm is None:
            lm = self.landmarks[j] = self._new_landmark(j, *usable[0], graph, update.values)
        for e, i in usable:
            plane = self.planes[e][i]
            predicted = self._predict(lm, e)
            _, flipped = orient_measurement(plane.coefficients, predicted)
            if flipped:
                if self.config.flipped_normals == "reject":
                    self.stats.rejected_flips += 1
                    continue
                self.stats.flipped += 1
                plane = plane.flipped()
            if not self._within_gate(plane.coefficients, predicted):
                self.stats.gated += 1
                continue
            self._plane_factor(lm, e, plane, graph, self._robust_planes)
            self._factor_landmark[(e, i)] = j
            lm.last_seen, lm.last_index = (e, plane.coefficients), i
        lm.last_epoch = k
        update.timestamps[lm.key] = float(k)
        if lm.anchor_key is not None:
            update.timestamps[lm.anchor_key] = float(k)

    def _plane_factor(
        self, lm: _Landmark, e: int, plane: Plane, graph: gtsam.NonlinearFactorGraph, robust: bool
    ) -> None:
        """A plane factor of observation ``plane`` (oriented) from ``X(e)`` on ``lm``."""
        cov = plane_factor_covariance(plane, self.config, self.deskew, e, share=self.plane_share)
        noise = plane_noise(cov, isotropic_normal=lm.anchor_key is None)
        key = F(e) if self.deskew is not None and e in self.deskew.frames else X(e)
        self._update.planes[graph.size()] = (e, plane)
        if lm.anchor_key is None:
            graph.add(plane_factor(key, lm.key, plane.coefficients, noise))
        else:
            make = partial(anchored_plane_factor, key, lm.anchor_key, lm.key, plane.coefficients)
            self._add(graph, make, noise, robust)
        self.stats.plane_factors += 1

    def _predict(self, lm: _Landmark, epoch: int) -> np.ndarray:
        """(4,) the landmark as epoch ``epoch`` should see it, for the flip and gate checks:
        from the track's last accepted observation carried over the (short) gap between the
        two epochs, so that drift of the initial estimate along a long track does not turn
        good observations into "wrong associations"; the landmark's estimate before it."""
        if lm.last_seen is None:
            return predict_plane(self.poses[epoch], lm.plane_world)
        e_last, seen = lm.last_seen
        world = plane_from_anchor(self.poses[e_last], seen)
        return predict_plane(self.poses[epoch], world)

    def _within_gate(self, measured: np.ndarray, predicted: np.ndarray) -> bool:
        """Whether an oriented plane observation (4,) agrees with its prediction (4,)."""
        cos_angle = float(np.clip(measured[:3] @ predicted[:3], -1.0, 1.0))
        return (
            np.degrees(np.arccos(cos_angle)) <= self.config.gate_normal_deg
            and abs(measured[3] - predicted[3]) <= self.config.gate_offset_m
        )

    def update_estimates(self, values: gtsam.Values, since: int = 0) -> None:
        """Refresh ``poses`` and the landmarks' world planes from an estimate ``values``
        (holding some of the graph's variables): epochs ``>= since`` and the landmarks seen
        since then."""
        for e in range(since, self.n_epochs):
            if values.exists(X(e)):
                self.poses[e] = values.atPose3(X(e)).matrix()
        for lm in self.landmarks.values():
            if lm.last_epoch < since or not values.exists(lm.key):
                continue
            plane = np.asarray(values.atOrientedPlane3(lm.key).planeCoefficients())
            if lm.anchor_key is not None:
                if values.exists(lm.anchor_key):
                    lm.T_world_anchor = values.atPose3(lm.anchor_key).matrix()
                assert lm.T_world_anchor is not None  # set with the anchor key
                plane = plane_from_anchor(lm.T_world_anchor, plane)
            lm.plane_world = plane

    def landmark_planes(self) -> dict[int, np.ndarray]:
        """Landmark id -> (4,) current world plane ``(n, d)``."""
        return {j: lm.plane_world.copy() for j, lm in self.landmarks.items()}

    def forget(self, before: int) -> None:
        """Drop stored planes of epochs older than ``before`` (memory in long runs)."""
        for e in [e for e in self.planes if e < before]:
            del self.planes[e]
        for key in [key for key in self._factor_landmark if key[0] < before]:
            del self._factor_landmark[key]
