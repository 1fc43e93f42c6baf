"""Twists extrapolated along their recent change (the streaming deskewing's, see
:mod:`planodom.odometry.deskew`): the trend tried for a suspect epoch (``odometry.
map_trend_rescue``, ``odometry.pairwise_trend_rescue``) and the lead of a plane-map
epoch's own twist to its sweep's middle (``odometry.map_twist_lead``)."""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from planodom.config import OdometryConfig
from planodom.odometry.bridge_robust import rate_variance
from planodom.odometry.motion_model import predicted_motion
from planodom.odometry.relative import RelativePose, Status


def predicted_twist(
    twist: np.ndarray,
    measured: bool,
    recent: deque[np.ndarray],
    velocities: deque[np.ndarray],
    against_map: bool,
    prediction: str = "mean",
    model: str = "constant_velocity",
    z_unobserved: str = "held",
) -> np.ndarray:
    """(6,) the constant-velocity twist (rad/s, m/s) for the next epoch after a step of own
    twist ``twist`` (6,) whose translation was ``measured`` or not: the angular rate of the
    step, and the median linear velocity of the last ``velocity_window`` steps whose
    translation was measured (``velocities``, appended to: one wrong translation must not
    steer the deskewing and the prior of the following epochs; a degenerate step only
    repeats its prior). ``against_map``: the plane-map pipeline, see below (``recent``,
    appended to); ``prediction`` (``planemap.prediction``): there the mean of the recent
    twists ("mean"), the last one ("last"), or the recent ones extrapolated one epoch
    along their trend ("trend", :func:`trend_twist`; the mean before 4 of them). ``model``
    (``odometry.motion_model``, pairwise pipelines only): what
    :func:`planodom.odometry.motion_model.predicted_motion` keeps of the pairwise one.
    ``z_unobserved`` (pairwise; ``odometry.unobserved_vertical`` for a step that did not
    observe z, else "held"): what its vertical velocity counts as: "held", its own (the
    prior's it kept); "zero"; "measured", the median of the window's (which then hold only
    measured ones or copies of them), zero with none, so a bridge's never enters."""
    rate = twist[:3]
    if against_map:
        # The map pipeline registers a scan against a map, not against a scan deskewed
        # the same way: a deskewing error e moves its estimate by about -e (a plane
        # seen at time t moves by e t), so deskewing with the last step's twist, or
        # extracting again with the epoch's own, oscillates from epoch to epoch (the
        # simulated paper loop, lidar32: 4 cm rms). It predicts the mean twist of the
        # last velocity_window steps (0.44 cm there), and extracts again with the mean
        # of the twist used and the epoch's own (register_deskewed, against_map).
        recent.append(twist.copy())
        if prediction == "last":
            return twist.copy()
        if prediction == "trend" and len(recent) >= 4:
            return trend_twist(np.array(recent))
        return np.mean(np.array(recent), axis=0)
    if z_unobserved != "held":  # the solver kept the prior's z: nothing measured it
        kept = [v[2] for v in velocities] if z_unobserved == "measured" else []
        vz = float(np.median(kept)) if kept else 0.0
        twist = np.r_[twist[:5], vz]
    if measured:
        velocities.append(twist[3:])
    if model == "nonholonomic_degenerate":  # only after a step that did not measure both
        model = "constant_velocity" if measured else "nonholonomic"
    if not velocities:
        return predicted_motion(np.concatenate((rate, twist[3:])), model)
    return predicted_motion(np.concatenate((rate, column_median(np.array(velocities)))), model)


def column_median(rows: np.ndarray) -> np.ndarray:
    """``np.median(rows, axis=0)`` (the same values) of finite ``rows`` (W, D), W >= 1,
    from one sort (asked once an epoch, where numpy's median costs more than the rest
    of the prediction): the middle row of the sorted columns, or for even W the sum of
    the two middle ones halved, as numpy's mean of them."""
    s = np.sort(rows, axis=0)
    h = len(s) // 2
    return s[h].copy() if len(s) % 2 else (s[h - 1] + s[h]) / 2


def trend_twist(
    recent: np.ndarray, x: np.ndarray | None = None, at: float | None = None
) -> np.ndarray:
    """(6,) the twist one epoch after the last of ``recent`` (W, 6) (W >= 4, one an epoch;
    or, given their epochs ``x`` (W,), at epoch ``at``), along the straight-line fit of
    each component, its slope shrunk by how well the
    fit's residuals determine it (``slope (1 - var_slope / slope^2)``, at least 0): a
    turn that tightens steadily is followed, a rate that only shakes from epoch to epoch
    (suspension roll and pitch) is averaged as by the mean. Least squares by hand: six
    independent fits of a handful of points, with their residuals."""
    w = len(recent)
    x = np.arange(w, dtype=float) if x is None else np.asarray(x, dtype=float)
    at = float(x[-1]) + 1.0 if at is None else float(at)
    centre = float(x.mean())
    x = x - centre
    mean = recent.mean(axis=0)
    sxx = float(x @ x)
    slope = x @ (recent - mean) / sxx
    resid = recent - mean - np.outer(x, slope)
    var_slope = np.sum(resid**2, axis=0) / (w - 2) / sxx
    shrink = np.clip(1.0 - var_slope / np.maximum(slope**2, 1e-300), 0.0, 1.0)
    return mean + shrink * slope * (at - centre)


def pairwise_trend(
    recent: Sequence[tuple[int, np.ndarray]],
    k: int,
    base: np.ndarray | None,
    config: OdometryConfig,
) -> np.ndarray | None:
    """(6,) the twist a lost epoch ``k`` of a pairwise pipeline is tried with last
    (``config.pairwise_trend_rescue``): the angular rate along the trend of the
    ``recent`` (epoch, own twist (6,)) of epochs that measured it, extrapolated to ``k``
    (:func:`trend_twist`), the velocity ``base``'s (the predicted or held twist); None
    when off, without ``base`` or before 4 of them."""
    if not config.pairwise_trend_rescue or base is None or len(recent) < 4:
        return None
    x = np.array([j for j, _ in recent], dtype=float)
    trend = trend_twist(np.array([tw for _, tw in recent]), x, float(k))
    return np.r_[trend[:3], base[3:]]


def map_trend(
    recent: Sequence[np.ndarray], config: OdometryConfig, prediction: str = "mean"
) -> np.ndarray | None:
    """(6,) the twist a plane-map epoch suspect with the mean of the ``recent`` twists
    (6,) is tried with (``config.map_trend_rescue``, :func:`trend_twist`); with
    ``prediction`` "trend" (``planemap.prediction``: the epoch was deskewed with that
    trend) their mean instead; None when off or before 4 of them."""
    if not config.map_trend_rescue or len(recent) < 4:
        return None
    if prediction == "trend":
        return np.mean(np.array(recent), axis=0)
    return trend_twist(np.array(recent))


@dataclass(frozen=True)
class Lead:
    """How a plane-map epoch registered at its sweep's middle is extracted again
    (``config.map_twist_lead``, :func:`map_lead`).

    Attributes:
        previous: (6,) the previous epoch's own twist, rad/s and m/s, its velocity NaN
            where not led (None: not measured, nothing is led).
        previous_dt: the previous step's seconds.
        rate_tolerance_deg_s, speed_tolerance_mps, iterations: replace ``odometry.
            deskew_rate_tolerance_deg_s``, ``deskew_speed_tolerance_mps`` and
            ``deskew_iterations`` (``odometry.map_lead_*``).
        previous_var: the previous own rate's stated variance (3,) (``map_lead_shrink``).
        vertical_tolerance_mps: the vertical velocity's own tolerance (None: with the
            velocity's; ``odometry.map_lead_vertical_tolerance_mps``).
    """

    previous: np.ndarray | None
    previous_dt: float
    rate_tolerance_deg_s: float
    speed_tolerance_mps: float
    iterations: int
    previous_var: np.ndarray | None = None
    vertical_tolerance_mps: float | None = None

    def led(
        self, own: np.ndarray, measured: bool, dt: float, relative: RelativePose | None = None
    ) -> np.ndarray:
        """(6,) ``own`` led along its change since ``previous`` (:func:`led_twist`); with
        ``previous_var`` (``odometry.map_lead_shrink: stated``) and ``relative``, the step
        ``own`` was measured by, its rate's lead shrunk by :func:`shrunk_lead`."""
        if self.previous is None:
            return own
        out = led_twist(own, measured, dt, self.previous, self.previous_dt)
        if self.previous_var is None or relative is None:
            return out
        variance = self.previous_var + rate_variance(relative, dt)
        out[:3] = own[:3] + shrunk_lead(out[:3] - own[:3], own[:3] - self.previous[:3], variance)
        return out


def shrunk_lead(lead: np.ndarray, change: np.ndarray, variance: np.ndarray) -> np.ndarray:
    """(3,) a rate's ``lead`` (rad/s) scaled per axis by the Wiener gain ``c^2 / (c^2 +
    v)`` of the ``change`` ``c`` (3,) it extrapolates, two epochs' own rates apart, whose
    noise has the ``variance`` ``v`` (3,, (rad/s)^2: both steps' stated rate variances).
    A change within its noise is mostly noise, and leading by it amplifies the noise
    (``own + 1/2 (own - previous)``: 1.6x the rate's standard deviation); a change far
    beyond it is the motion's, led in full. Axes whose variance is unknown (NaN) or whose
    change is zero keep ``lead`` as it is."""
    c2 = change**2
    gain = np.ones(3)
    known = np.isfinite(variance) & (c2 > 0)
    gain[known] = c2[known] / (c2[known] + np.maximum(variance[known], 0.0))
    return gain * np.nan_to_num(lead)


def map_lead(
    recent: Sequence[tuple[int, np.ndarray]],
    k: int,
    times: Sequence[float],
    last: RelativePose | None,
    config: OdometryConfig,
    variances: Sequence[np.ndarray] = (),
) -> Lead | None:
    """How epoch ``k`` of a plane map registered at its sweep's middle is extracted again
    (``config.map_twist_lead``; None when off): its own twist led along the change from
    the previous epoch's, taken from ``recent`` (epoch, own twist) of the epochs that
    measured their rate (none when the previous epoch is not among them), its velocity
    only when the lead covers it and that step (``last``) measured it; ``times``: the
    epochs' so far, seconds; ``variances``: the stated rate variances (3,) of ``recent``
    (one each), which ``odometry.map_lead_shrink: stated`` shrinks the lead by."""
    mode = config.map_twist_lead
    if mode == "off":
        return None
    previous, previous_dt = None, 0.0
    if recent and recent[-1][0] == k - 1 and len(times) >= 2 and last is not None:
        previous = np.array(recent[-1][1], dtype=np.float64, copy=True)
        previous_dt = float(times[-1] - times[-2])
        if mode == "rate" or last.status is not Status.OK:
            previous[3:] = np.nan
    previous_var = None
    shrink = config.map_lead_shrink == "stated" and previous is not None
    if shrink and len(variances) == len(recent):
        previous_var = np.asarray(variances[-1], dtype=np.float64)
    return Lead(previous, previous_dt, config.map_lead_rate_tolerance_deg_s,
                config.map_lead_speed_tolerance_mps, config.map_lead_iterations,
                previous_var, config.map_lead_vertical_tolerance_mps)  # fmt: skip


def led_twist(
    own: np.ndarray, measured: bool, dt: float, previous: np.ndarray, previous_dt: float
) -> np.ndarray:
    """(6,) an epoch's ``own`` twist (rad/s, m/s; the mean over its step of ``dt`` seconds,
    i.e. the twist ``dt / 2`` before the epoch's time) led to the epoch's time along its
    change since ``previous`` (6,), the mean over the step of ``previous_dt`` seconds
    before: ``own + dt / (dt + previous_dt) (own - previous)`` (the two means are
    ``(dt + previous_dt) / 2`` apart; exact under a constant acceleration to second
    order). Components where ``previous`` is NaN, and the velocity unless ``measured``,
    stay ``own``'s."""
    out = np.array(own, dtype=np.float64, copy=True)
    if dt <= 0 or previous_dt <= 0:
        return out
    change = (dt / (dt + previous_dt)) * (out - previous)
    use = np.isfinite(change)
    if not measured:
        use[3:] = False
    out[use] += change[use]
    return out
