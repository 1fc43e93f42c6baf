"""When to extract an epoch again with a better twist: the deskewing policy.

A scan whose points are spread in time is deskewed with a constant-velocity twist (body
frame, rad/s and m/s). The twist of the last estimate is only a prediction; once the
epoch's own relative pose is known, :func:`register_deskewed` decides whether to extract
it again:

1. deskewed with the prediction; when that leaves the epoch unresolved or degenerate, or
   finds far fewer planes than the epoch before (under half, or under two), also without
   deskewing: a wrong twist must not lock the odometry out (on a random world at 2 cm, a
   wrong early velocity deskewed every later epoch into zero planes for 16 epochs in a
   row). Against a plane map whose prediction is the mean of the recent twists
   (``planemap.prediction: mean``, :func:`planodom.odometry.trend.predicted_twist`), the
   twist extrapolated along their trend is tried first (``odometry.map_trend_rescue``):
   the mean lags a turn that tightens (issue 11's world 9, 32 beams: 13 deg/s predicted
   where the sweep turned at 23, the epoch lost with it and without deskewing, ATE 0.55
   m; resolved with the trend's 21 deg/s, ATE 0.033 m); with the trend as the prediction
   (``trend``, the default), the mean is tried instead. The best of them is kept:
   status first, then plane count (distinct surfaces with ``odometry.deskew_rank:
   surfaces`` or ``surfaces_first``, :mod:`.surfaces`). After an
   unresolved epoch no twist is predicted (a twist never outlives an unresolved epoch),
   but the one held from before it is tried the same way when the epoch extracted
   without deskewing is suspect: on a 2D-rig world a turn left only the ground without
   it, and the gap went on for 7 epochs. On the pairwise pipelines, an epoch still lost
   (unresolved, or far fewer planes) is tried last with the angular rate along the
   trend of the recent measured ones (``odometry.pairwise_trend_rescue``, off by
   default);
2. up to ``deskew_iterations`` times: with the epoch's own angular rate and (when its
   translation was measured) velocity (against a plane map: their mean with the twist
   used, see ``against_map``) wherever they differ from the twist used by more
   than ``deskew_rate_tolerance_deg_s`` / ``deskew_speed_tolerance_mps`` (with
   ``odometry.deskew_rate_lead``, off, the rate led to the points, :mod:`.centred_twist`);
   a reference epoch that was never deskewed (the first) is extracted again with it too; with
   ``odometry.deskew_significance_gate`` (off by default) only what the step measured
   beyond its noise counts (:func:`significant_twist`: a parked lidar's step is noise,
   not a motion to deskew with); with ``odometry.deskew_change_gate`` (off) only where
   it differs from the twist used beyond its own error (:mod:`.change_gate`) (with
   ``odometry.reference_refresh_guard``, off by default, its old planes are brought
   back when the estimate against the new ones is worse; with
   ``odometry.refresh_keep_resolved``, off, only when it is unresolved). An epoch
   kept without deskewing is refined only once its translation is measured (never with
   a velocity of zero nobody measured). A new estimate is kept while its status (with
   ``surfaces``: status, then distinct surfaces) does not get worse, and always once
   the reference was extracted again (the earlier estimate was made against the
   reference's old planes).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from planodom.config import AssociationConfig, OdometryConfig
from planodom.extraction.memo import identity_memo
from planodom.geometry import Plane, se3_log
from planodom.odometry.relative import RelativePose, Status, replaced
from planodom.odometry.surfaces import Ranking, by_planes
from planodom.odometry.twist_refine import Blend, next_twist, refined_own
from planodom.odometry.untwisted_try import suspect
from planodom.planes import PlaneSet
from planodom.scan import Scan

if TYPE_CHECKING:
    from planodom.odometry.centred_twist import Centring
    from planodom.odometry.planemap import MapEstimate
    from planodom.odometry.trend import Lead


@dataclass(frozen=True, eq=False)
class EpochEstimate:
    """One extraction of an epoch and the relative pose it gives.

    Attributes:
        planes: the extracted planes (base frame); plane_set: the same as arrays.
        twist: (6,) the twist the scan was deskewed with (None: not deskewed).
        relative: the relative pose to the reference epoch (``prev`` .. ``curr``).
        step: (4, 4) ``T_{k-1}_k`` it implies for the last step.
        reference_planes: the reference epoch's planes it was estimated against (its
            association indices refer to them).
        map_estimate: the plane-map odometry's registration to commit when this
            estimate is kept (``pipeline: map``), else None.
        twist_offset: (6,) what the deskewing of the two epochs took off the step's
            twist, rad/s and m/s (:meth:`own_twist`); None: nothing.
        span_epochs: with ``odometry.gap_end_rate: span``, the epochs its measured
            relative pose spans when its reference is further back than the epoch before
            (a step that ends a bridged stretch): its own twist is then the relative
            pose's over that span (:meth:`own_twist`); 1: the step's.
    """

    planes: list[Plane]
    plane_set: PlaneSet
    twist: np.ndarray | None
    relative: RelativePose
    step: np.ndarray
    reference_planes: list[Plane]
    map_estimate: MapEstimate | None = None
    twist_offset: np.ndarray | None = None
    span_epochs: int = 1

    @cached_property
    def _step_log(self) -> np.ndarray:
        """(6,) ``se3_log(step)``, computed once: :meth:`own_twist` is asked for it again
        after each deskewing pass, and a scipy rotation log per call cost a fifth of a
        solve."""
        return se3_log(self.step)

    def own_twist(self, dt: float) -> np.ndarray:
        """(6,) the epoch's twist, rad/s and m/s, over the ``dt`` seconds of its step: the
        step's twist plus ``twist_offset`` where it was measured (all of it when the
        status is OK, the angular rate when degenerate, nothing when unresolved: a
        bridge); with ``planemap.twist_estimation``, the twist its registration measured
        (unless unresolved). With ``span_epochs`` above 1 (a measured step ending a
        bridged stretch, epochs at a constant period ``dt``) the twist of its relative
        pose over the span instead of the step's."""
        status = self.relative.status
        registered = None if self.map_estimate is None else self.map_estimate.twist
        if registered is not None and status is not Status.UNRESOLVED:
            return registered  # planemap.twist_estimation: measured in the registration
        own = self._step_log / dt
        if self.span_epochs > 1 and status is not Status.UNRESOLVED:
            # the step holds the bridged epochs' error, taken back at once; the relative
            # pose measured over the span does not (odometry.gap_end_rate, GAP17)
            own = se3_log(self.relative.T_prev_curr) / (dt * self.span_epochs)
        if self.twist_offset is None or status is Status.UNRESOLVED:
            return own
        return own + (
            self.twist_offset if status is Status.OK else np.r_[self.twist_offset[:3], 0, 0, 0]
        )


#: ``estimate(twist, source=None) -> EpochEstimate``: extract the epoch deskewed with
#: ``twist`` (None: not deskewed) and estimate its relative pose; ``source``: the estimate
#: whose own twist ``twist`` was refined from (None: predicted or held).
Estimator = Callable[..., EpochEstimate]
#: ``refresh_reference(twist) -> bool``: extract the reference epoch again with ``twist``
#: when it was never deskewed; returns whether it did.
Refresher = Callable[[np.ndarray], bool]


def registered_prediction(best: EpochEstimate, dt: float, predicted: np.ndarray) -> np.ndarray:
    """(6,) the twist predicted for the next epoch when the plane map measured the epoch's
    own twist (``planemap.twist_estimation``, ``best.map_estimate.twist``, unless
    unresolved): that twist, extrapolated by its measured acceleration over ``dt`` s
    (the step's, ``registered_acceleration``), not the mean of the recent twists, which
    lags a swing; else ``predicted``."""
    est = best.map_estimate
    if est is None or est.twist is None or best.relative.status is Status.UNRESOLVED:
        return predicted
    return est.twist if est.acceleration is None else est.twist + est.acceleration * dt


def time_spread(scan: Scan) -> bool:
    """Whether the scan's points carry times that differ (deskewing can matter)."""
    return bool(scan.t is not None and len(scan.t) and _spread_and_mean(scan.t)[0] > 0)


def with_deskew(
    result: RelativePose, scan: Scan, twist: np.ndarray | None, interval_s: float
) -> RelativePose:
    """``result`` with its epoch's ``time_spread`` (``scan``'s), the ``twist`` (6,) (rad/s,
    m/s; None: not deskewed) its points were deskewed with, their first and last time
    (s; also when not deskewed, if spread) and the ``interval_s`` (s) since its reference
    epoch."""
    spread = time_spread(scan)
    if not spread:
        return replaced(result, time_spread=spread, interval_s=interval_s)
    assert scan.t is not None
    times = (float(np.min(scan.t)), float(np.max(scan.t)))  # also when not deskewed
    used = None if twist is None else np.array(twist, dtype=float)
    return replaced(
        result, time_spread=spread, deskew_twist=used, deskew_times=times,
        interval_s=interval_s,
    )  # fmt: skip


@identity_memo
def _spread_and_mean(t: np.ndarray) -> tuple[float, float]:
    """``np.ptp(t)`` and ``np.mean(t)`` of a scan's times (N,), N >= 1, seconds; memoised
    (:mod:`planodom.extraction.memo`: a scan's times are read-only): an epoch asks for
    them with every estimate."""
    return float(np.ptp(t)), float(np.mean(t))


def centred_times(scan: Scan) -> bool:
    """Whether the scan's point times are centred on its reference time (their middle
    within 1 % of their span: a sweep registered at its middle, see
    :mod:`planodom.odometry.planemap.midtime`, up to rounding and a column). With
    ``planemap.reference_time: middle``, a plane-map epoch's own twist is then used as it
    is, not averaged with the one used (:func:`register_deskewed`, ``against_map``): a
    deskewing error distorts such a scan but does not shift it as a whole. (Not for
    other centred scans: on KITTI 0005 with its declared sweep, stamped mid-sweep, the
    own twist as it is gave 0.0693 deg / 3.77 cm RPE against 0.0717 deg / 3.63 cm.)"""
    if scan.t is None or len(scan.t) == 0:
        return False
    lo, hi = float(np.min(scan.t)), float(np.max(scan.t))
    return abs(lo + hi) <= 0.02 * (hi - lo)


def twist_offset(
    scan: Scan | None, twist: np.ndarray | None, reference_twist: np.ndarray | None, dt: float
) -> np.ndarray | None:
    """(6,) the offset between the twist of the step an epoch's planes give and its true
    twist (:meth:`EpochEstimate.own_twist`), rad/s and m/s; None when nothing is offset.
    The epoch's ``scan`` was deskewed with ``twist``, its reference with
    ``reference_twist`` (None: not deskewed), ``dt`` seconds before.

    A plane's points are seen at about the mean point time ``tm`` after the epoch time;
    deskewed with a twist ``u`` off the true one by ``e``, they sit where the epoch's pose
    off by ``-e tm`` would put them. So the step from the reference epoch (deskewed with
    ``u_r``) to this one (``u``) is off by ``tm (e_r - e)``, and its twist by ``(tm / dt)
    (e_r - e)``; over the two epochs' equal true twist, that is ``(tm / dt) (u_r - u)``,
    and the true twist is the step's plus ``(tm / dt) (u - u_r)``. Taken as it is, the
    step's twist swings around the truth from one extraction to the next. (Measured on a
    2D-rig world at sigma = 0, tm / dt = 0.48: an epoch deskewed with 14.6 deg/s and
    5.4 m/s against a reference deskewed with 10.7 deg/s and 3.9 m/s, where the truth was
    10.1 deg/s and 3.7 m/s, gave a step of 7.2 deg/s and 2.4 m/s; with the offset, 9.0
    and 3.1. On the quick start, noise seeds 0-5, horizontal ATE with / without it: mean
    0.039 / 0.038 m, each seed within 0.024-0.059 m either way (seed 0: 0.052 / 0.030),
    3D 0.076 / 0.079 m: no bias, one draw's spread.)
    """
    if dt <= 0 or scan is None or scan.t is None or not len(scan.t):
        return None
    if twist is None or reference_twist is None:
        # an epoch extracted without a twist is not "deskewed with zero": the 2D-rig path
        # then extrapolates each wall seen in several time windows to the epoch time
        return None
    tm = _spread_and_mean(scan.t)[1]
    return (tm / dt) * (twist - reference_twist) if tm != 0.0 else None


def register_deskewed(
    predicted: np.ndarray | None,
    dt: float,
    estimate: Estimator,
    refresh_reference: Refresher,
    config: OdometryConfig,
    previous_planes: int = 0,
    held: np.ndarray | None = None,
    against_map: bool = False,
    trend: np.ndarray | None = None,
    lost_trend: np.ndarray | None = None,
    restore_reference: Callable[[], None] | None = None,
    lead: Lead | None = None,
    bounds: tuple[AssociationConfig, Callable[[], None]] | None = None,
    rank: Ranking = by_planes,
    centring: Centring | None = None,
    blend: Blend | None = None,
    trend_status: bool = False,
) -> EpochEstimate:
    """The best estimate of a time-spread epoch (module docstring).

    Args:
        predicted: (6,) the constant-velocity twist predicted for the epoch (None: none).
        dt: seconds since the previous epoch; config: its ``deskew_*`` fields.
        estimate, refresh_reference: see :data:`Estimator`, :data:`Refresher`.
        previous_planes: planes of the previous epoch (under half of them now: suspect).
        held: (6,) the twist held from before an unresolved epoch, tried only when
            ``predicted`` is None and the epoch extracted without it is suspect.
        against_map: the estimate registers the epoch against a map (the plane-map
            odometry), not against an epoch deskewed the same way: a deskewing error
            ``e`` then moves the epoch's own twist by about ``-e`` (own = 2 true - used),
            so it is extracted again with the mean of the twist used and its own
            (unless ``config.map_twist_offset``: then its own twist has that offset
            taken off, as for the pairwise pipelines). Not for centred times (odometry.py).
        trend: (6,) the twist extrapolated along the recent change of the twists (None:
            none): tried first when the epoch deskewed with ``predicted`` is suspect (a
            prediction lags a turn that tightens); with ``trend_status`` (``odometry.
            turn_trend_keep: status``) kept only for a better status, not by ``rank``.
        lost_trend: (6,) tried last when the epoch is still lost (unresolved, or far fewer
            planes than the epoch before; None: none; :func:`.trend.pairwise_trend`): an
            unresolved epoch measured no rate for step 2, and has nothing better.
        restore_reference: brings back the reference's planes a refresh replaced (None:
            never), when the estimate against the new ones is worse (:func:`_restorer`).
        lead: the lead of the epoch's own twist and the tolerances and iterations
            that replace ``config``'s (:class:`planodom.odometry.trend.Lead`); None: none.
        bounds: the motion bounds the run assumes and what brings the reference's planes
            back (``odometry.deskew_bounds_guard``, :func:`_left_bounds`; None: off).
        rank: how extractions are ranked (``odometry.deskew_rank``, :func:`.surfaces.ranking`).
        centring, blend: the refinements' own rate led to the epoch's points (``odometry.
            deskew_rate_lead``) / weighed against the prediction (``twist_blend``); None: off.
    """
    first = (previous_planes, held, trend, lost_trend, rank, trend_status)
    best = _first_estimate(predicted, dt, estimate, *first, config.untwisted_try)
    iterations = config.deskew_iterations if lead is None else lead.iterations
    before = None  # (used, own) of the refinement before: odometry.deskew_rate_solve
    for _ in range(iterations if dt > 0 else 0):
        if best.relative.status is Status.UNRESOLVED:
            break
        if best.twist is None and best.relative.status is not Status.OK:
            break  # never deskew with a linear velocity nobody measured (v = 0)
        used = np.zeros(6) if best.twist is None else best.twist
        measured = best.relative.status is Status.OK
        own = refined_own(best, dt, used, measured, config, against_map, lead, blend, centring)
        new, before = next_twist(own, used, measured, config, lead, before, best.relative, dt)
        stale_reference = refresh_reference(new)
        if not stale_reference and np.array_equal(new, used):
            break
        again = estimate(new, best)
        if _left_bounds(again, best, bounds, stale_reference):
            break
        if _worse(again, best, rank, config):
            restore = _restorer(again, restore_reference, config)
            if stale_reference and restore is not None:
                restore()  # the estimate made against the old planes holds again
            if not stale_reference or restore is not None:
                break
        # once the reference was extracted again, an estimate made against its old
        # extraction (or the map seeded with it) refers to planes that are gone
        best = again
    return best


def guarded(config: OdometryConfig) -> bool:
    """Whether a refresh of the reference may be undone (``odometry.reference_refresh_guard``
    or ``odometry.refresh_keep_resolved``): then ``restore_reference`` is passed."""
    return config.reference_refresh_guard or config.refresh_keep_resolved


def _restorer(
    again: EpochEstimate, restore_reference: Callable[[], None] | None, config: OdometryConfig
) -> Callable[[], None] | None:
    """What brings back the reference's planes when the refinement ``again`` is worse than
    the (resolved) estimate before it: ``restore_reference`` with
    ``reference_refresh_guard``; with ``refresh_keep_resolved`` only when ``again`` is
    unresolved; None (``again`` kept once the reference was extracted again) otherwise,
    whether or not ``restore_reference`` is given."""
    if config.reference_refresh_guard:
        return restore_reference
    lost = config.refresh_keep_resolved and again.relative.status is Status.UNRESOLVED
    return restore_reference if lost else None


def _worse(
    again: EpochEstimate, best: EpochEstimate, rank: Ranking, config: OdometryConfig
) -> bool:
    """Whether the refinement ``again`` is worse than ``best``: its status
    (``odometry.deskew_rank: planes`` or ``surfaces_first``), or its rank (``surfaces``:
    status, then distinct surfaces; :mod:`.surfaces`)."""
    if config.deskew_rank != "surfaces":
        return again.relative.status.rank < best.relative.status.rank
    return rank(again) < rank(best)


def beyond_bounds(step: np.ndarray, bounds: AssociationConfig) -> bool:
    """Whether ``step`` (4, 4), ``T_prev_curr`` of one epoch, exceeds the motion bounds
    ``bounds.max_rotation_deg`` (its rotation angle) or ``max_translation_m``."""
    cos = np.clip((np.trace(step[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)
    turned = float(np.arccos(cos)) > np.radians(bounds.max_rotation_deg)
    return bool(turned or float(np.linalg.norm(step[:3, 3])) > bounds.max_translation_m)


def _left_bounds(
    again: EpochEstimate,
    best: EpochEstimate,
    bounds: tuple[AssociationConfig, Callable[[], None]] | None,
    stale_reference: bool,
) -> bool:
    """Whether ``again`` (not unresolved), extracted with ``best``'s own twist, left the
    motion bounds ``bounds[0]`` within which ``best`` measured its step: then the
    refinement ends with ``best`` kept, and when the reference was extracted again for
    ``again`` (``stale_reference``) its planes from before are brought back
    (``bounds[1]``). Always False when ``bounds`` is None (the guard off)."""
    if bounds is None or again.relative.status is Status.UNRESOLVED:
        return False
    left = beyond_bounds(again.step, bounds[0]) and not beyond_bounds(best.step, bounds[0])
    if left and stale_reference:
        bounds[1]()  # the reference's planes from before the refresh
    return left


def _first_estimate(
    predicted: np.ndarray | None,
    dt: float,
    estimate: Estimator,
    previous_planes: int,
    held: np.ndarray | None,
    trend: np.ndarray | None,
    lost_trend: np.ndarray | None,
    rank: Ranking,
    trend_status: bool = False,
    untwisted_try: str = "suspect",
) -> EpochEstimate:
    """Step 1 of the module docstring: the best of the epoch deskewed with ``predicted``
    and, when that is suspect, with ``trend``, none or ``held`` and ``lost_trend`` (see
    :func:`register_deskewed`), by ``rank`` (:func:`.surfaces.ranking`); ``trend`` by
    status alone with ``trend_status``; ``untwisted_try`` (``odometry.untwisted_try``,
    :func:`.untwisted_try.suspect`) says which epochs are suspect."""
    best = estimate(predicted)
    few = _few(best, previous_planes)
    others: list[np.ndarray | None] = [] if trend is None or predicted is None else [trend]
    if predicted is not None or held is not None:
        others.append(None if predicted is not None else held)
    if dt > 0 and suspect(best, few, previous_planes, untwisted_try):
        for other in others:
            alternative = estimate(other)
            if trend_status and trend is not None and other is trend:
                better = alternative.relative.status.rank > best.relative.status.rank
            else:
                better = rank(alternative) > rank(best)
            if better:
                best = alternative
    if dt > 0 and lost_trend is not None and _lost(best, previous_planes):
        alternative = estimate(lost_trend)
        if rank(alternative) > rank(best):
            best = alternative
    return best


def judged(best: EpochEstimate, judge: Callable[[MapEstimate], MapEstimate]) -> EpochEstimate:
    """The epoch's final estimate ``best`` as the plane map ``judge`` s it (its
    :meth:`~planodom.odometry.planemap.PlaneMapOdometry.judged`: a step beyond the motion
    bounds bridged, with ``planemap.motion_bound_gate``). Only the estimate kept is judged,
    not every extraction tried on the way: a wrong first attempt is what step 2 corrects."""
    if best.map_estimate is None:
        return best
    final = judge(best.map_estimate)
    if final is best.map_estimate:
        return best
    rel = final.relative.between(best.relative.prev, best.relative.curr)
    return replace(best, relative=rel, step=rel.T_prev_curr, map_estimate=final)


def _few(candidate: EpochEstimate, previous_planes: int) -> bool:
    """Far fewer planes than the epoch before (under half, or under two)."""
    return len(candidate.planes) < max(2.0, 0.5 * previous_planes)


def _lost(candidate: EpochEstimate, previous_planes: int) -> bool:
    """Unresolved, or far fewer planes than the epoch before."""
    return candidate.relative.status is Status.UNRESOLVED or _few(candidate, previous_planes)


def prefer_streaming(given: EpochEstimate, previous_planes: int) -> bool:
    """Whether an epoch deskewed by a given motion (:func:`planodom.odometry.run.
    redeskewed_run`) is suspect, as in step 1 of the module docstring: unresolved, or far
    fewer planes than the epoch before; then the streaming deskewing is tried too. (A
    degenerate epoch is not suspect: a straight street makes every epoch degenerate, and
    the streaming deskewing, with as many planes, would be kept for no reason.)"""
    return _lost(given, previous_planes)


def keep_first(first: EpochEstimate, second: EpochEstimate) -> bool:
    """Whether ``first`` is at least as good as ``second``: status, then plane count."""
    return by_planes(first) >= by_planes(second)
