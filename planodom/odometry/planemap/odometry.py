"""Streaming plane-landmark odometry against a local plane map (``pipeline: map``).

Per scan (:meth:`PlaneMapOdometry.estimate`, then :meth:`PlaneMapOdometry.commit` of the
estimate kept; estimating does not change the state, so an epoch may be extracted again
with another twist and estimated again):

1. prediction: constant velocity (the last relative motion; ``planemap.degenerate_velocity``);
2. registration of the scan's plane moments against the map from the prediction, with
   gates from the model's past deviations (:func:`.register.register`);
3. when that is suspicious (the first pair; fewer than ``min_inliers`` inlier planes or
   ``min_inlier_fraction`` of the planes; an inlier fraction below ``suspect_ratio``
   times the recent median; a tilt change beyond ``max_tilt_change_deg``), other
   hypotheses are registered too: zero velocity (gates by the size of the last motion),
   the scan-to-scan registration with widening gates, LDA without motion bounds
   (:mod:`.fallback`). The winner is the resolved hypothesis (if any) with the lowest
   robust point-to-plane cost of ALL the scan's planes against the map
   (:func:`.register.score`), not the one with the most inliers (a wrong pose can gather
   many weak associations); hypotheses that flip the base's z axis are rejected;
4. the 6x6 information gives the covariance; rotation directions with a 1-sigma above
   ``unobserved_rotation_deg`` make the epoch UNRESOLVED (the prediction is kept) when
   all are, else take the prediction's rotation about them (``rotation_partly_observed``,
   ``planemap.partial_rotation``); a translation direction above ``unobserved_translation_m``
   DEGENERATE (the prediction is kept along it, with its uncertainty:
   ``planemap.degenerate_translation``); a step beyond the run's motion bounds is marked
   (``beyond_bounds``) and, with ``planemap.motion_bound_gate``, made UNRESOLVED and
   ``inconsistent`` (bridged by constant velocity) by :meth:`PlaneMapOdometry.judged`,
   once the epoch's final estimate is chosen (not each extraction tried: the streaming
   odometry corrects wrong attempts);
5. the map is updated (:func:`.landmarks.update_map`); after a detected failure (an
   unresolved epoch whose scan had enough planes) it is rebuilt from the current scan.

Planes need their moments (``support.scatter``, ``n_points``, ``n_rows``); planes without
them are not used.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from planodom.config import PlanodomConfig
from planodom.geometry import Plane, invert_transform
from planodom.median import median
from planodom.odometry.deskew import beyond_bounds
from planodom.odometry.planemap import fallback
from planodom.odometry.planemap.bias import fitted_bias
from planodom.odometry.planemap.ctreg import TwistRegistration, corrected_planes, register_twist
from planodom.odometry.planemap.deskew_weights import change_covariance, led_weights
from planodom.odometry.planemap.few_inliers import observed_few
from planodom.odometry.planemap.landmarks import PlaneMap, update_map
from planodom.odometry.planemap.led_twist import led_registration, timed_planes
from planodom.odometry.planemap.moments import Moments, scan_sigma
from planodom.odometry.planemap.pose import relative_pose
from planodom.odometry.planemap.register import Registration, ScanPlanes, register, score
from planodom.odometry.planemap.twist_filter import TwistFilter, filtered_registration
from planodom.odometry.relative import RelativePose, Status
from planodom.planes import PlaneSet
from planodom.rotvec import rotation_vectors
from planodom.scan import Scan


def _angle(R: np.ndarray) -> float:
    return float(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))


def _orthonormalised(T: np.ndarray) -> np.ndarray:
    """``T`` with its rotation projected on SO(3): poses are chained through closed-form
    inverses (transposes), where a rotation off SO(3) would double its error per scan."""
    U, _, Vt = np.linalg.svd(T[:3, :3])
    out = T.copy()
    out[:3, :3] = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    return out


def _tilt(R: np.ndarray) -> float:
    """Angle (rad) by which ``R`` turns the z axis."""
    return float(np.arccos(np.clip(R[2, 2], -1.0, 1.0)))


@dataclass(frozen=True, eq=False)
class MapEstimate:
    """One scan's registration, to be committed (:meth:`PlaneMapOdometry.commit`).

    Attributes:
        relative: the relative pose from the previous scan (``prev``/``curr`` unset).
        T: (4, 4) world from scan. T_pred: the prediction it started from.
        used: (K,) indices of the planes used (those with moments).
        cur: their registration inputs (None without planes). reg: the winning
            registration (None when there was nothing to register against).
        beyond_bounds: its step exceeds the run's motion bounds (see
            :meth:`PlaneMapOdometry.judged`).
        bias_m: the laser bias fitted to its inlier residuals (m; ``planemap.laser_bias:
            fitted``), None when not fitted.
        deskew: (the twist (6,) the planes were deskewed with, None: not deskewed; the
            seconds since the previous scan), as given to :meth:`PlaneMapOdometry.estimate`.
        twist: (6,) the scan's own twist measured by the continuous-time registration
            (``planemap.twist_estimation``, :mod:`.ctreg`), rad/s and m/s, at its
            reference time; None when not measured. acceleration: (6,) its rate of
            change, rad/s^2 and m/s^2 (``registered_acceleration``, or the filter's
            with ``planemap.twist_filter``), else None. twist_filter: the filter after
            the scan (:mod:`.twist_filter`; None: not updated).
    """

    relative: RelativePose
    T: np.ndarray
    T_pred: np.ndarray
    used: np.ndarray
    cur: ScanPlanes | None
    reg: Registration | None
    plane_set: PlaneSet
    against: tuple[PlaneMap, int] | None = None
    beyond_bounds: bool = False
    bias_m: float | None = None
    deskew: tuple[np.ndarray | None, float | None] = (None, None)
    twist: np.ndarray | None = None
    acceleration: np.ndarray | None = None
    twist_filter: TwistFilter | None = None


class PlaneMapOdometry:
    """Plane-landmark odometry (module docstring); ``config.planemap`` holds its settings."""

    def __init__(self, config: PlanodomConfig | None = None) -> None:
        self.config = config or PlanodomConfig()
        self.map = PlaneMap()
        self.pose = np.eye(4)
        self.velocity = np.eye(4)
        self.frame = -1
        self._dev_sse = np.zeros(2)
        self._dev_n = np.zeros(2, dtype=int)  # deviations counted: rotation, translation
        self._dev_axes = np.zeros(6)  # their squared components (rotation vector, translation)
        self._fractions: list[float] = []
        self._prev: PlaneSet | None = None
        self.bias_m = self.config.planemap.laser_bias_m  # the fitted one, when fitted
        self._twist_filter = TwistFilter()

    # ------------------------------------------------------------------ gates

    def sigmas(self) -> tuple[float, float]:
        """RMS rotation (rad) and translation (m) deviations of the prediction so far (the
        translation's over the epochs that measured it, see :meth:`commit`)."""
        pm = self.config.planemap
        if self._dev_n[0] == 0:
            return np.radians(pm.initial_rotation_deg), pm.initial_translation_m
        rms = np.sqrt(self._dev_sse / np.maximum(self._dev_n, 1))
        return float(rms[0]), float(rms[1]) if self._dev_n[1] else pm.initial_translation_m

    # ------------------------------------------------------------------ one scan

    def estimate(
        self, planes: Sequence[Plane], twist: np.ndarray | None = None, dt: float | None = None,
        led: tuple[np.ndarray, float] | None = None,
    ) -> MapEstimate:  # fmt: skip
        """Register one scan's planes (base frame); the state is not changed. ``twist``
        (6,): the one they were deskewed with (None: not deskewed), ``dt``: seconds since
        the previous scan; both only for ``planemap.twist_estimation``; ``led``: the led
        twist's variance and the span (``planemap.lead_weights``, :mod:`.deskew_weights`)."""
        used = np.array(
            [
                k
                for k, p in enumerate(planes)
                if p.support is not None
                and p.support.scatter is not None
                and not 0 < p.support.n_rows < self.config.planemap.min_rows
            ],
            dtype=np.intp,
        )
        cur = self._scan_planes(planes, used, led)
        return self._estimate(used, cur, PlaneSet.from_planes(planes), (twist, dt))

    def _estimate(
        self,
        used: np.ndarray,
        cur: ScanPlanes | None,
        plane_set: PlaneSet,
        deskew: tuple[np.ndarray | None, float | None] = (None, None),
    ) -> MapEstimate:
        """:meth:`estimate` of the planes ``used`` of ``plane_set`` (inputs ``cur``)."""
        T_pred = self.pose @ self.velocity
        against = (self.map, self.frame)
        if self.frame < 0 or cur is None or len(self.map) == 0:
            status = Status.OK if self.frame < 0 else Status.UNRESOLVED
            rel = relative_pose(self, self.velocity, None, status)
            T = self.pose if self.frame < 0 else T_pred
            return MapEstimate(rel, T, T_pred, used, cur, None, plane_set, against)
        reg = self._best_registration(T_pred, cur, plane_set)
        ok = self._resolved(reg, cur)
        ct, filt = self._registered_twist(reg, cur, deskew) if ok else (None, None)
        own = ct is not None and cur.led_var is None  # lead_weights: unknown, the pose only
        if ct is not None:
            reg = replace(reg, T=ct.T)
            if self.config.planemap.twist_map_update == "corrected":
                cur = corrected_planes(cur, ct)
        rel, T = self._result(reg, ok, T_pred, cur, used)
        measured = rel.status is not Status.UNRESOLVED
        beyond = measured and self._beyond_bounds(rel)
        bias = None
        if measured and self.config.planemap.laser_bias == "fitted":
            inl = reg.weights > 0.5
            upper = self.config.planemap.laser_bias_m
            bias = fitted_bias(self.map, reg.T, cur, reg.landmarks[inl], reg.planes[inl], upper)
        twist = acceleration = None
        if ct is not None and own and measured:
            twist = (np.zeros(6) if deskew[0] is None else deskew[0]) + ct.correction
            if self.config.planemap.twist_estimation == "registered_acceleration":
                acceleration = ct.acceleration
            if filt is not None and filt.state is not None:
                twist, acceleration = filt.state.mean[:6].copy(), filt.state.mean[6:].copy()
        return MapEstimate(rel, T, T_pred, used, cur, reg, plane_set, against, beyond, bias,
                           deskew, twist, acceleration, filt)  # fmt: skip

    def _registered_twist(
        self, reg: Registration, cur: ScanPlanes, deskew: tuple[np.ndarray | None, float | None]
    ) -> tuple[TwistRegistration | None, TwistFilter | None]:
        """The continuous-time registration from ``reg`` (``planemap.twist_estimation``,
        :mod:`.ctreg`); None when off, without time moments, before any motion was
        measured or without the step's ``dt``. Its prior: the twist's error per axis the
        constant-velocity model's RMS deviation so far along that axis (rotation vector
        and translation components, scan frame) over ``dt`` (the twist deskewed with is
        the last one measured: it is off by the change of the twist over a step), the
        acceleration's twice that over ``dt`` (the rate may change by the twist's error
        within half an epoch). With ``planemap.twist_filter``, the filter's prediction
        instead, and the filter after the scan (else None). A scan with the led twist's
        variance (``lead_weights: unknown``): that prior instead (:mod:`.led_twist`)."""
        mode, dt = self.config.planemap.twist_estimation, deskew[1]
        if cur.led_var is not None:  # lead_weights: unknown, the led twist's variance
            return led_registration(self.map, reg, cur, self.config.planemap.gn_iterations), None
        if mode == "none" or cur.time_moments is None or self._dev_n[0] == 0:
            return None, None
        if dt is None or dt <= 0:
            return None, None
        rms = np.sqrt(self._dev_axes / np.repeat(np.maximum(self._dev_n, 1), 3))
        if self._dev_n[1] == 0:
            rms[3:] = self.config.planemap.initial_translation_m
        sd = np.maximum(rms / dt, 1e-9)
        iterations = self.config.planemap.gn_iterations
        if self.config.planemap.twist_filter == "kalman":
            used = np.zeros(6) if deskew[0] is None else deskew[0]
            order = 2 if mode == "registered_acceleration" else 1
            return filtered_registration(
                self.map, reg, cur, (used, dt), sd, order, self._twist_filter, iterations
            )
        if mode == "registered_acceleration":
            sd = np.r_[sd, 2.0 * sd / dt]
        return register_twist(self.map, reg, cur, cur.time_moments, sd, iterations), None

    def judged(self, est: MapEstimate) -> MapEstimate:
        """An epoch's final estimate, bridged by constant velocity (UNRESOLVED and
        ``inconsistent``) when its step is beyond the motion bounds and
        ``planemap.motion_bound_gate`` is on: it contradicts them, lost track rather than
        a measurement (the map is then rebuilt from the scan, :meth:`commit`). Call
        before committing it; ``est`` itself when nothing changes."""
        if not (est.beyond_bounds and self.config.planemap.motion_bound_gate):
            return est
        rel = relative_pose(self, self.velocity, None, Status.UNRESOLVED)
        stage = est.reg.stage if est.reg is not None else ""
        rel = _with_associations(replace(rel, inconsistent=True), np.zeros((0, 2), np.intp), stage)
        return replace(est, relative=rel, T=est.T_pred, beyond_bounds=False, bias_m=None)

    def _scan_planes(
        self, planes: Sequence[Plane], used: np.ndarray, led: tuple[np.ndarray, float] | None
    ) -> ScanPlanes | None:
        if len(used) == 0:
            return None
        m = Moments.of_planes([planes[k] for k in used])
        normals = np.array([planes[k].normal for k in used])
        sigma = scan_sigma(m, self.config.extraction.range_noise_m)
        weights = led_weights(self.config.planemap, planes, used, led)
        change = self._dev_sse, self._dev_n  # planemap.deskew_variance
        bias, cov = weights or (
            self.bias_m,
            change_covariance(self.config.planemap, planes, used, *change),
        )
        cur = ScanPlanes.of(m, normals, sigma, bias, cov)
        return timed_planes(self.config.planemap, cur, planes, used, led)

    def _resolved(self, reg: Registration, cur: ScanPlanes) -> bool:
        """Enough inliers (or fewer that fix every direction, :mod:`.few_inliers`), and no
        flip of the z axis relative to the last pose."""
        pm = self.config.planemap
        n_inl = len(reg.inliers)
        R_rel = self.pose[:3, :3].T @ reg.T[:3, :3]
        tilt_ok = _tilt(R_rel) <= np.radians(pm.max_tilt_change_deg)
        enough = n_inl >= pm.min_inliers or observed_few(reg.H, n_inl, self.config)
        return enough and n_inl >= pm.min_inlier_fraction * len(cur) and tilt_ok

    def _best_registration(
        self, T_pred: np.ndarray, cur: ScanPlanes, plane_set: PlaneSet
    ) -> Registration:
        """Step 2, and step 3 when suspicious (module docstring)."""
        pm = self.config.planemap
        s_r, s_t = self.sigmas()
        best = register(self.map, T_pred, cur, s_r, s_t, pm, "map")
        frac = len(best.inliers) / max(len(cur), 1)
        typical = median(np.array(self._fractions[-20:])) if self._fractions else 1.0
        ok = self._resolved(best, cur)
        suspicious = not ok or frac < pm.suspect_ratio * typical or self._dev_n[0] == 0
        if not (suspicious and pm.fallback and self._prev is not None):
            return best
        vr, vt = _angle(self.velocity[:3, :3]), float(np.linalg.norm(self.velocity[:3, 3]))
        guesses = [(self.pose, max(s_r, vr), max(s_t, vt), "zero-velocity")]
        wide_r, wide_t = max(s_r, np.radians(1.0)), max(s_t, 0.5)
        for name, T_rel in (
            ("widening", fallback.widening(self._prev, plane_set, cur.sigma, pm.min_inliers)),
            ("lda", fallback.lda_hypothesis(self._prev, plane_set, cur.sigma, pm)),
        ):
            if T_rel is not None and _tilt(T_rel[:3, :3]) <= np.radians(pm.max_tilt_change_deg):
                guesses.append((self.pose @ T_rel, wide_r, wide_t, name))
        candidates = [best]
        for T0, gr, gt, name in guesses:
            candidates.append(register(self.map, T0, cur, gr, gt, pm, name))
        keys = [(not self._resolved(c, cur), self._beyond(c.T), score(self.map, c.T, cur, pm))
                for c in candidates]  # fmt: skip
        return candidates[min(range(len(candidates)), key=lambda i: keys[i])]

    def _result(
        self, reg: Registration, ok: bool, T_pred: np.ndarray, cur: ScanPlanes, used: np.ndarray
    ) -> tuple[RelativePose, np.ndarray]:
        """Step 4: the relative pose and the world pose kept."""
        status = Status.UNRESOLVED
        T = T_pred
        if ok:
            T = reg.T
            status = Status.OK
        T_rel = invert_transform(self.pose) @ T
        rel = relative_pose(self, T_rel, reg.H if ok else None, status)
        if rel.status is Status.UNRESOLVED:
            T = T_pred
            rel = relative_pose(self, self.velocity, None, Status.UNRESOLVED)
            ok = False
        elif self._predicted_translation(rel) or (
            self.config.planemap.kept_pose == "reported"
            and not np.array_equal(rel.T_prev_curr, T_rel)
        ):
            # its unobserved translation: the prediction's; with ``kept_pose: reported``
            # whatever of it came from the prediction (the vertical, rotation about some
            # axes): the map update and the next prediction rest on the pose reported
            T = self.pose @ rel.T_prev_curr
        assoc = self._associations(reg, used) if ok else np.zeros((0, 2), dtype=np.intp)
        return _with_associations(rel, assoc, reg.stage), T

    def _predicted_translation(self, rel: RelativePose) -> bool:
        """Whether ``rel``'s unobserved translation is the prediction's."""
        prediction = self.config.planemap.degenerate_translation == "prediction"
        return prediction and rel.status is Status.DEGENERATE

    def _beyond(self, T: np.ndarray) -> bool:
        """Whether the step to the world pose ``T`` (4, 4) exceeds the motion bounds, for
        ranking hypotheses (``planemap.hypothesis_bounds``; "score": never)."""
        if self.config.planemap.hypothesis_bounds == "score":
            return False
        return self._step_beyond_bounds(invert_transform(self.pose) @ T)

    def _beyond_bounds(self, rel: RelativePose) -> bool:
        """Whether ``rel``'s step exceeds the motion bounds the run assumes."""
        return self._step_beyond_bounds(rel.T_prev_curr)

    def _step_beyond_bounds(self, step: np.ndarray) -> bool:
        """Whether ``step`` (4, 4), T_prev_curr, exceeds the association's motion bounds."""
        return beyond_bounds(step, self.config.association)

    def _associations(self, reg: Registration, used: np.ndarray) -> np.ndarray:
        """(L, 2) (plane index in the previous scan, plane index in this scan) through the
        landmarks the previous scan observed last; injective."""
        inl = reg.weights > 0.5
        lm, jj = reg.landmarks[inl], reg.planes[inl]
        seen = (self.map.last_seen[lm] == self.frame) & (self.map.last_index[lm] >= 0)
        pairs = np.column_stack([self.map.last_index[lm[seen]], used[jj[seen]]])
        if len(pairs) == 0:
            return np.zeros((0, 2), dtype=np.intp)
        _, first_prev = np.unique(pairs[:, 0], return_index=True)
        pairs = pairs[np.sort(first_prev)]
        _, first_curr = np.unique(pairs[:, 1], return_index=True)
        return pairs[np.sort(first_curr)].astype(np.intp)

    # ------------------------------------------------------------------ state

    def reseed(self, planes: Sequence[Plane]) -> None:
        """Build the map again from the first scan's ``planes`` (extracted again, e.g.
        deskewed once a twist is known) while only that scan is in it; else nothing."""
        if self.frame != 0:
            return
        self.__init__(self.config)  # type: ignore[misc]
        self.commit(self.estimate(planes))

    def commit(self, est: MapEstimate) -> None:
        """Make ``est`` the scan's result: pose, velocity, deviation statistics, map.

        An estimate made against another map (the first scan seeded again since, or
        another scan committed) is registered again first: its associations index
        landmarks of that map."""
        if est.against is not None and (
            est.against[0] is not self.map or est.against[1] != self.frame
        ):
            est = self.judged(self._estimate(est.used, est.cur, est.plane_set, est.deskew))
        first, pm = self.frame < 0, self.config.planemap
        self.frame += 1
        T = _orthonormalised(est.T)
        if not first:
            dev = invert_transform(est.T_pred) @ T
            # a degenerate epoch whose translation is the prediction's along its unobserved
            # directions did not measure how far off the prediction is: counting its zero
            # there would shrink the gates and the prediction's sigma it is given
            counted = int(not self._predicted_translation(est.relative))
            self._dev_sse += [_angle(dev[:3, :3]) ** 2, counted * float(dev[:3, 3] @ dev[:3, 3])]
            self._dev_n += [1, counted]
            rotvec = rotation_vectors(dev[None, :3, :3])[0]
            self._dev_axes += np.r_[rotvec**2, counted * dev[:3, 3] ** 2]
            if est.relative.status is not Status.DEGENERATE or pm.degenerate_velocity == "step":
                self.velocity = _orthonormalised(invert_transform(self.pose) @ T)
        self.pose = T
        self._prev = est.plane_set
        unresolved = est.relative.status is Status.UNRESOLVED
        self._twist_filter = self._twist_filter.after(unresolved, est.twist_filter, est.deskew[1])
        cur = est.cur
        if cur is None:
            return
        assoc, w = np.full(len(cur), -1), np.zeros(len(cur))
        measured = est.relative.status is not Status.UNRESOLVED
        if measured and est.reg is not None:
            assoc[est.reg.planes], w[est.reg.planes] = est.reg.landmarks, est.reg.weights
            self._fractions.append(len(est.reg.inliers) / max(len(cur), 1))
        elif not first and len(cur) >= pm.min_inliers and len(self.map):
            self.map = PlaneMap()  # a detected failure: rebuild from this scan
        if est.bias_m is not None:
            self.bias_m = est.bias_m
        bias = self.bias_m if est.bias_m is not None else cur.bias  # lead_weights: the scan's
        update_map(self.map, est.T, cur.m, cur.normals, assoc, w, self.frame, est.used,
                   cur.sigma, pm, bias)  # fmt: skip


def uses_plane_map(config: PlanodomConfig, scan: Scan | None) -> bool:
    """Whether the plane-map odometry runs on a sequence whose first epoch is ``scan``:
    pipeline "map", or "auto" with delta 1 on a scan that takes the lidar extraction path."""
    pipeline = config.odometry.pipeline
    if pipeline == "auto" and config.odometry.delta == 1 and scan is not None:
        from planodom.extraction.pipeline import choose_mode

        return choose_mode(scan, config.extraction) == "lidar"
    return pipeline == "map"


def _with_associations(rel: RelativePose, assoc: np.ndarray, stage: str) -> RelativePose:
    from planodom.association import PairAssociations
    from planodom.odometry.relative import SolverDiagnostics

    info = SolverDiagnostics(f"map:{stage}", PairAssociations.empty())
    return replace(rel, associations=assoc, diagnostics=info)
