"""Streaming plane odometry: one epoch in, one pose out (:class:`PlaneOdometry`).

Per epoch k: extract planes (deskewed with the constant-velocity twist of the last
estimate, :mod:`planodom.odometry.deskew`), associate them with the planes of epoch
``k - delta`` (a short history is kept), estimate the relative pose with the
constant-velocity prediction as prior, and chain: ``T_world_k = T_world_{k-delta} @
T_{k-delta}_k``. The first epoch defines the world frame (identity). When the reference
epoch has fewer than two planes, the latest earlier epoch with two or more is used instead
(bounds scaled by the gap). An unresolved epoch (no associated non-parallel pair) is
bridged by constant velocity (the last increment's twist times the elapsed time, its rate
along the trend with ``odometry.bridge_rate``; standing still before any motion is known):
its result has ``status == Status.UNRESOLVED`` and that bridge as ``T_prev_curr``. No
motion is carried across a gap in the epoch times: see :data:`.epoch_time.RESET_PERIODS`.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from planodom.config import PlanodomConfig
from planodom.geometry import Plane, orthonormalised, twist_step
from planodom.odometry.bridge_robust import rate_variance
from planodom.odometry.bridge_trend import bridge, bridge_twist
from planodom.odometry.centred_twist import centring
from planodom.odometry.chain import inverse_chain
from planodom.odometry.deskew import (
    EpochEstimate,
    centred_times,
    guarded,
    judged,
    keep_first,
    prefer_streaming,
    register_deskewed,
    registered_prediction,
    time_spread,
    twist_offset,
    with_deskew,
)
from planodom.odometry.deskew_secant import epoch_deskew_config
from planodom.odometry.epoch_extraction import extract_epoch
from planodom.odometry.epoch_time import is_gap, next_epoch_time
from planodom.odometry.extractor import Extractor
from planodom.odometry.first_epoch import first_round, reextracted_first
from planodom.odometry.kept_epoch import KeptEpoch as _Epoch
from planodom.odometry.lead_acceleration import LeadAcceleration, lead_acceleration
from planodom.odometry.led_variance import led_variance
from planodom.odometry.lost_narrow import narrow_if_lost
from planodom.odometry.moment_when import refined_commit, refined_estimate
from planodom.odometry.motion_model import vertical_prediction
from planodom.odometry.rate_prediction import RatePredictor
from planodom.odometry.refresh_held import held_refresh
from planodom.odometry.relative import RelativePose, Status, replaced
from planodom.odometry.solver import config_for_gap, estimate_relative_pose
from planodom.odometry.split_reference import split_reference
from planodom.odometry.start_epochs import StartEpochs
from planodom.odometry.surfaces import fragment_count, ranking
from planodom.odometry.trend import map_lead, map_trend, pairwise_trend, predicted_twist
from planodom.odometry.turn_trend import turn_trend
from planodom.odometry.twist_refine import significant_twist
from planodom.odometry.twist_sigma import TwistSigma, TwistUncertainty, widened_if_lost
from planodom.odometry.vertical_offset import step_twist_offset
from planodom.planes import PlaneSet
from planodom.scan import Scan, check_is_scan

if TYPE_CHECKING:
    from planodom.odometry.planemap import PlaneMapOdometry


class PlaneOdometry:
    """Streaming plane odometry (``register_epoch`` per scan, or ``register_planes``).

    Args:
        config: the pipeline configuration (default: defaults).
        extractor: see :data:`Extractor`; default :func:`planodom.extraction.extract_planes`.
        sensor_origins: sensor positions in the base frame, metres ((3,) or (S, 3) by
            ring), passed to the extractor to orient normals; None: its default.

    Attributes:
        config: the pipeline configuration.
        poses: ``T_world_base`` (4, 4) of every registered epoch (the first is identity).
        times: reference time of every epoch, seconds.
        results: per epoch the :class:`RelativePose` from its reference epoch
            (``result.prev``: ``k - delta``, or, when that one has fewer than two planes,
            the latest earlier epoch that has) to it; None for the first epoch.
        planes: the planes of every epoch (base frame), as last extracted: a reference
            epoch that was never deskewed (the first) is extracted again with a twist.
        superseded: epochs whose result indexes planes (its own or its reference's) that
            were extracted again later, so not ``planes``.
        twist: (6,) constant-velocity body twist, rad/s and m/s, predicted for the next
            epoch (angular rate of the last step, ``odometry.rate_prediction``'s or,
            with ``odometry.twist_blend``, weighed against the prediction; median recent
            measured linear velocity); None before the second epoch.
    """

    def __init__(
        self,
        config: PlanodomConfig | None = None,
        extractor: Extractor | None = None,
        sensor_origins: np.ndarray | None = None,
    ):
        self.config = config or PlanodomConfig()
        self.extractor = extractor
        self.sensor_origins = sensor_origins
        self.poses: list[np.ndarray] = []
        self.times: list[float] = []
        self.results: list[RelativePose | None] = []
        self.planes: list[list[Plane]] = []
        self.superseded: set[int] = set()
        self.twist: np.ndarray | None = None
        self._history: deque[_Epoch] = deque(maxlen=self.config.odometry.delta)  # last delta
        self._last_usable: _Epoch | None = None  # the last with a non-parallel plane pair
        self._velocities: deque[np.ndarray] = deque(maxlen=self.config.odometry.velocity_window)
        self._steps: list[np.ndarray] = []  # T_{k-1}_k per epoch (identity first)
        self._gap_configs: dict[int, PlanodomConfig] = {1: self.config}
        self._map: PlaneMapOdometry | None = None  # when the pipeline is (resolves to) "map"
        self.acceleration: LeadAcceleration | None = None  # odometry.map_lead_acceleration
        self._recent: deque[np.ndarray] = deque(maxlen=self.config.odometry.velocity_window)
        # pairwise pipelines: (epoch, own twist) of the last epochs that measured the rate
        self._rates: deque[tuple[int, np.ndarray]] = deque(maxlen=self._recent.maxlen)
        self._rate_vars: deque[np.ndarray] = deque(maxlen=self._recent.maxlen)  # their variances
        self._twist_sigma = TwistUncertainty(self.config.odometry)
        self._rate = RatePredictor(self.config.odometry)  # odometry.rate_prediction
        self._undo: tuple = ()  # what the last reference refresh replaced
        self._gaps: set[int] = set()  # epochs after a gap in the epoch times (is_gap)
        self.start = StartEpochs(self.config.odometry.start_refresh)  # the undeskewed start

    @property
    def last_pose(self) -> np.ndarray | None:
        """``T_world_base`` (4, 4) of the last epoch (None before the first)."""
        return self.poses[-1] if self.poses else None

    @property
    def last_relative(self) -> RelativePose | None:
        """The relative pose found for the last epoch (None before the second)."""
        return self.results[-1] if self.results else None

    @property
    def last_planes(self) -> list[Plane]:
        """The planes of the last epoch."""
        return self._history[-1].planes if self._history else []

    @property
    def pairwise(self) -> bool:
        """Whether a pairwise pipeline runs, not the plane map (decided at the first epoch)."""
        return self._map is None

    @property
    def twist_uncertainty(self) -> TwistUncertainty:
        """The model of the deskewing twist's error (:mod:`.twist_sigma`)."""
        return self._twist_sigma

    @property
    def reference_index(self) -> list[int]:
        """Per epoch the epoch it was associated with (``results[k].prev``); -1 first."""
        return [-1 if r is None else r.prev for r in self.results]

    def register_epoch(
        self, scan: Scan, time: float | None = None, deskewed: Scan | None = None
    ) -> np.ndarray:
        """Extract the planes of one epoch and register them; returns ``T_world_base``.

        Args:
            scan: the epoch's points in the base frame (with per-point times if known).
            time: the epoch's reference time, seconds (default: previous + epoch period).
            deskewed: the same points already deskewed to ``time`` by a better motion
                model (:func:`planodom.odometry.run.redeskewed_run`): extracted first,
                and kept unless :func:`planodom.odometry.deskew.prefer_streaming` says
                ``scan`` deskewed as usual might do better.
        """
        check_is_scan(scan)
        t = self._next_time(time)
        k = len(self.poses)
        if k == 0:
            self._start_map(scan)
            if deskewed is not None:  # a zero twist: deskewed already (never refreshed)
                return self._commit_first(self._new_epoch(0, deskewed, np.zeros(6)), t)
            return self._commit_first(self._new_epoch(0, scan, None), t)
        if deskewed is not None:
            # a zero twist: deskewed already (its times kept give a lidar's range-image
            # columns; with None a 2D rig's would be split in time windows)
            given = self._estimate_scan(deskewed, t, np.zeros(6))
            if not prefer_streaming(given, len(self.last_planes)):
                epoch = _Epoch(k, given.planes, given.plane_set, deskewed, np.zeros(6))
                return self._commit(epoch, given, t)
        estimate = split_reference(self, partial(  # odometry.split_reference
            self._estimate_scan, scan, t, prior_sigma=self._twist_sigma.predicted()))  # fmt: skip
        if self.config.odometry.deskew and time_spread(scan):
            dt, ocfg, pm = t - self.times[-1], self.config.odometry, self.config.planemap
            # a twist never outlives an unresolved epoch: until one is measured again, epochs are
            # extracted without it (still the prior and bridge; tried when that is suspect)
            unresolved = getattr(self.last_relative, "status", None) is Status.UNRESOLVED
            refresh, previous = held_refresh(self, unresolved), len(self.last_planes)
            rates = self._rates if self._map is None else ()  # bridge_rate: pairwise only
            held = bridge_twist(self.twist, rates, k, ocfg, self._rate_vars) if unresolved else None
            twist = None if unresolved else self._rate.deskewing(self.twist)
            ocfg = epoch_deskew_config(ocfg, k in self._gaps, self._map is None)
            against_map = self._map is not None and self.twist is not None
            trend = (map_trend(self._recent, ocfg, pm.prediction) if against_map
                     else turn_trend(rates, k, scan.t, dt, twist, ocfg))  # fmt: skip
            middle = self.config.planemap.reference_time == "middle" and centred_times(scan)
            pairwise, middle = self._map is None, middle and self._map is not None
            damped = against_map and not middle  # see centred_times
            lost_trend = pairwise_trend(self._rates, k, self.twist, ocfg) if pairwise else None
            restore = self._restore_reference if pairwise and guarded(ocfg) else None
            led = middle and k not in self._gaps  # a lead never crosses a gap
            lead = map_lead(self._rates, k, self.times, self.results[-1], ocfg,
                            self._rate_vars) if led else None  # fmt: skip
            self.acceleration = lead_acceleration(lead, scan, self._history, dt, ocfg)
            guard = pairwise and ocfg.deskew_bounds_guard
            bounds = (self.config.association, self._restore_reference) if guard else None
            blend = self._twist_sigma.blend.bound(self._map)  # odometry.twist_blend
            best = self.start.vehicle(self, scan, t, register_deskewed(
                twist, dt, estimate, refresh, ocfg, previous, held, damped, trend, lost_trend,
                restore, lead, bounds, ranking(self.config, pairwise),
                centring(rates, k, scan.t, dt, self.config, self.last_relative),
                blend, pairwise and ocfg.turn_trend_keep == "status"))  # fmt: skip
            if k == 1 and ocfg.first_epoch_reextract:  # the second epoch: the first's rounds
                best = reextracted_first(
                    best, dt, ocfg, self._history[0], partial(first_round, self, scan, t)
                )
        else:
            best = estimate(None)
        best = narrow_if_lost(self, best, scan, t)  # odometry.lost_narrow_seed_deg
        twist = best.twist
        if deskewed is not None and keep_first(given, best):
            best, scan, twist = given, deskewed, np.zeros(6)
        return self._commit(_Epoch(k, best.planes, best.plane_set, scan, twist), best, t)

    def register_planes(self, planes: Sequence[Plane], time: float | None = None) -> np.ndarray:
        """Register an epoch given its planes (base frame); returns ``T_world_base`` (4, 4)."""
        t = self._next_time(time)
        epoch = _Epoch(len(self.poses), list(planes), PlaneSet.from_planes(planes))
        if not self.poses:
            self._start_map(None)
            return self._commit_first(epoch, t)
        return self._commit(epoch, self._estimate(epoch, t), t)

    def _start_map(self, scan: Scan | None) -> None:
        """Whether the plane map runs: pipeline "map", or "auto", delta 1, a lidar's scan."""
        from planodom.odometry.planemap import PlaneMapOdometry, uses_plane_map

        if uses_plane_map(self.config, scan):
            changes = self.config.planemap.extraction_changes()
            if changes:
                self.config = self.config.updated(changes, source="planemap")
            self._map = PlaneMapOdometry(self.config)

    def _next_time(self, time: float | None) -> float:
        """:func:`.epoch_time.next_epoch_time`; a gap (:func:`.is_gap`) noted, the map stopped."""
        t = next_epoch_time(time, self.times, self.config.odometry.epoch_period_s)
        if is_gap(self.times, t):
            self._gaps.add(len(self.poses))
            if self._map is not None:
                self._map.velocity = np.eye(4)  # predicted standing still
        return t

    def _extract(
        self, scan: Scan, twist: np.ndarray | None, sigma: TwistSigma | None = None,
        prior: TwistSigma | None = None,
    ) -> tuple[list[Plane], np.ndarray | None]:  # fmt: skip
        """The planes and the twist used: :func:`.epoch_extraction.extract_epoch`."""
        return extract_epoch(self, scan, twist, sigma, prior)

    def _new_epoch(
        self, k: int, scan: Scan, twist: np.ndarray | None, sigma: TwistSigma | None = None,
        prior: TwistSigma | None = None, led: tuple[np.ndarray, float] | None = None,
    ) -> _Epoch:  # fmt: skip
        planes, used = self._extract(scan, twist, sigma, prior)
        return _Epoch(k, planes, PlaneSet.from_planes(planes), scan, used, led=led)

    def _estimate_scan(
        self, scan: Scan, t: float, twist: np.ndarray | None,
        source: EpochEstimate | None = None, prior_sigma: TwistSigma | None = None,
    ) -> EpochEstimate:  # fmt: skip
        """Extract the scan deskewed with ``twist`` and estimate its relative pose; the
        twist's sigma is ``prior_sigma`` (predicted or held), or from ``source`` when it
        was refined from that estimate's own twist (:mod:`.twist_sigma`)."""
        sigma = prior_sigma if twist is not None else None
        if source is not None and twist is not None and self.times:
            sigma = self._twist_sigma.refined(source, t - self.times[-1], twist)
        k, ocfg, count = len(self.poses), self.config.odometry, fragment_count(self.config)
        led = led_variance(self, scan, t, twist, source)  # planemap.lead_weights
        extract = lambda s: self._estimate(self._new_epoch(k, scan, twist, s, sigma, led), t)  # noqa: E731
        dt, mode = t - self.times[-1], ocfg.twist_sigma
        agrees = partial(self._twist_sigma.consistent, dt=dt, prediction=self.twist, config=ocfg)
        return widened_if_lost(extract, sigma, mode, len(self.last_planes), agrees, count)

    def _estimate(self, epoch: _Epoch, t: float) -> EpochEstimate:
        """The relative pose of ``epoch`` (at time ``t``) from the reference epoch, and the
        step ``T_{k-1}_k`` it implies; poses are chained through steps (products of rigid
        transforms), never through a chained world pose's inverse: rounding cannot grow."""
        if self._map is not None:
            return self._estimate_map(epoch, t)
        reference = self._reference()
        T_ref_last, steps = np.eye(4), self._steps[reference.index + 1 :]  # T_{ref}_{k-1}
        for step in steps:
            T_ref_last = T_ref_last @ step
        T_last_ref = inverse_chain(T_ref_last, steps)
        dt = t - self.times[-1]
        prediction = None  # constant velocity: T_{ref}_k
        if self.twist is not None and dt > 0 and epoch.index not in self._gaps:
            prediction = T_ref_last @ twist_step(self.twist, dt)
        sigma = self._twist_sigma.predicted()[1] * dt  # the prediction's translation, m
        prior = prediction if self.config.odometry.use_motion_prior else None
        gap = epoch.index - reference.index
        config, planes = self._config_for_gap(gap), (reference.plane_set, epoch.plane_set)
        result = estimate_relative_pose(*planes, config, prior, sigma, step=True, gap=gap)
        ocfg, k = self.config.odometry, epoch.index  # bridged by constant velocity (its trend)
        result = refined_estimate(self, result, reference.planes, k, epoch.planes, planes)
        if result.status is Status.UNRESOLVED:
            bridged = bridge(prediction, T_ref_last, self.twist, dt, self._rates, k, ocfg,
                             self._rate_vars, (*planes, config, self._twist_sigma))  # fmt: skip
            result = replaced(result, T_prev_curr=bridged)
        result = result.between(reference.index, epoch.index)
        step = orthonormalised(T_last_ref @ result.T_prev_curr)
        offset = step_twist_offset(epoch, reference.twist, dt, result, ocfg)
        estimate = EpochEstimate(epoch.planes, epoch.plane_set, epoch.twist, result, step,
                                 reference.planes, twist_offset=offset)  # fmt: skip
        predicted = None if k in self._gaps else self.twist  # none across a gap
        bridging = bridge_twist(predicted, self._rates, k, ocfg, self._rate_vars)  # one off it
        return self._twist_sigma.gated(estimate, dt, predicted, T_ref_last, ocfg, bridging)

    def _estimate_map(self, epoch: _Epoch, t: float) -> EpochEstimate:
        """The plane-map odometry's estimate of ``epoch`` against its map (the previous
        epoch is the reference of the relative pose); committed in :meth:`_commit`."""
        assert self._map is not None
        reference = self._history[-1]
        dt = None if epoch.index in self._gaps else t - self.times[-1]  # no twist measured
        est = self._map.estimate(epoch.planes, epoch.twist, dt, epoch.led)
        result = est.relative.between(reference.index, epoch.index)
        step = orthonormalised(result.T_prev_curr)
        offset = None  # the deskewing's offset of the step's twist (twist_offset)
        if self.config.odometry.map_twist_offset and self.times:
            offset = twist_offset(epoch.scan, epoch.twist, reference.twist, t - self.times[-1])
        return EpochEstimate(epoch.planes, epoch.plane_set, epoch.twist, result, step,
                             reference.planes, est, twist_offset=offset)  # fmt: skip

    def _config_for_gap(self, gap: int) -> PlanodomConfig:
        if gap not in self._gap_configs:
            self._gap_configs[gap] = config_for_gap(self.config, gap)
        return self._gap_configs[gap]

    def _reference(self) -> _Epoch:
        """The epoch the next one is associated with (see ``results``)."""
        ref = self._history[0]
        if not ref.has_pair(self.config.association) and self._last_usable is not None:
            ref = self._last_usable
        return ref

    def _refresh_reference(self, twist: np.ndarray) -> bool:
        """Extract the reference epoch again with ``twist`` when it has a scan that was
        never deskewed (its pose is not changed) and was not brought back before
        (:meth:`_restore_reference`); returns whether it did."""
        ref = self._reference()
        if ref.scan is None or ref.twist is not None or ref.kept:
            return False
        if self._map is not None and ref.index != 0:
            return False  # the map holds the epoch's planes: only the first is seeded again
        was = ref.index in self.superseded
        self._undo = (ref, ref.planes, ref.plane_set, was, self._last_usable)
        self._set_planes(ref, *self._extract(ref.scan, twist, prior=self._twist_sigma.predicted()))
        if self.results[ref.index] is not None:
            self.superseded.add(ref.index)
        last = self._last_usable
        if ref.has_pair(self.config.association) and (last is None or last.index <= ref.index):
            self._last_usable = ref
        return True

    def _restore_reference(self) -> None:
        """Bring back the planes the last :meth:`_refresh_reference` replaced (the epoch's
        estimate against the new ones was worse); the epoch is not extracted again."""
        ref, planes, plane_set, superseded, last_usable = self._undo
        self._set_planes(ref, planes, None, plane_set)
        ref.kept, self._last_usable = True, last_usable
        if not superseded:
            self.superseded.discard(ref.index)

    def _set_planes(
        self, ref: _Epoch, planes: list[Plane], twist: np.ndarray | None,
        plane_set: PlaneSet | None = None,
    ) -> None:  # fmt: skip
        """Give ``ref`` its planes extracted again with ``twist`` (the map seeded again)."""
        ref.planes, ref.twist = planes, twist
        ref.plane_set = PlaneSet.from_planes(planes) if plane_set is None else plane_set
        self.planes[ref.index] = planes
        if self._map is not None and ref.index == 0:
            self._map.reseed(planes)

    def _commit_first(self, epoch: _Epoch, t: float) -> np.ndarray:
        if self._map is not None:
            self._map.commit(self._map.estimate(epoch.planes))
        self._append(epoch, np.eye(4), np.eye(4), None, t)
        return self.poses[-1]

    def _commit(self, epoch: _Epoch, best: EpochEstimate, t: float) -> np.ndarray:
        """Append the epoch with its pose from ``best.step``; update the twist."""
        best = refined_commit(self, best, epoch.index)  # moment_extractions: committed
        if self._map is not None:  # planemap.motion_bound_gate judges the final estimate
            best = judged(best, self._map.judged)
        dt = t - self.times[-1]
        gap = epoch.index in self._gaps  # no twist from its step: the one before is held
        if best.relative.status is Status.UNRESOLVED or gap:
            self._velocities.clear()  # stale velocities go with the twist (see register)
        if gap:
            self._recent.clear()
            self._rates.clear()
            self._rate_vars.clear()
            self._twist_sigma.blend.reset()
        elif dt > 0:
            measured = best.relative.status is Status.OK
            own = best.own_twist(dt)  # its rate blended with odometry.twist_blend:
            blended = self._twist_sigma.update(own, best.relative, dt, self._map)
            if best.relative.status is not Status.UNRESOLVED:
                self._rates.append((epoch.index, own))
                self._rate_vars.append(rate_variance(best.relative, dt))
            significant = significant_twist(blended, best.relative, dt, self.config.odometry)
            args = (significant, measured, self._recent, self._velocities, self._map is not None)
            prediction = vertical_prediction(self.config, best.relative)
            self.twist = registered_prediction(best, dt, predicted_twist(*args, *prediction))
            self.twist = self._rate.after(epoch.index, own, best.relative, self.twist, self._map)
        if best.map_estimate is not None and self._map is not None:
            self._map.commit(best.map_estimate)
            if gap:
                self._map.velocity = np.eye(4)  # not the motion across the gap
        T_world = orthonormalised(self.poses[-1] @ best.step)
        if best.reference_planes is not self.planes[best.relative.prev]:
            self.superseded.add(epoch.index)
        self._append(epoch, T_world, best.step, best.relative, t)
        return T_world

    def _append(
        self, epoch: _Epoch, T_world: np.ndarray, step: np.ndarray, result: RelativePose | None,
        t: float,
    ) -> None:  # fmt: skip
        if result is not None and epoch.scan is not None:
            result = with_deskew(result, epoch.scan, epoch.twist, t - self.times[result.prev])
        self.poses.append(T_world)
        self._steps.append(step)
        self.times.append(t)
        self.results.append(result)
        self.planes.append(epoch.planes)
        self._history.append(epoch)
        if epoch.has_pair(self.config.association):
            self._last_usable = epoch
        self.start.appended(self, epoch)
