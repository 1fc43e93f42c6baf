"""The angular rate an unresolved epoch is bridged with (``odometry.bridge_rate``).

An epoch whose planes do not fix its step is bridged by the prediction: the last
measured step's angular rate held over the stretch. In a turn that tightens steadily
(issue 11's 2D-rig world 6 at 6 mm, epochs 45-61: 9 -> 20 deg/s, about 0.7 deg/s more
each epoch) the held rate lags more with every bridged epoch, and the epoch after the
stretch is tried deskewed with it too (the held twist): epoch 51's far wall, deskewed with
11.3 deg/s for a true 12.7, came out 0.89 deg off in yaw under the true rotation (its
association right, truth id 86 on both sides), and that wrong rate (8.2 deg/s) was held
over the three epochs bridged after it. ``trend`` bridges with the rate along the
straight-line trend of the recent epochs that measured it
(:func:`planodom.odometry.trend.trend_twist`, its slope shrunk by how well the fit
determines it, so a rate that only shakes is averaged), extrapolated to the bridged
epoch but never more than ``bridge_trend_epochs`` past the last of them (a trend does
not run on through a whole lost stretch; past the bound the rate stays the bound's).
``median`` bridges with the component-wise median angular rate of the last
``bridge_median_steps`` epochs that measured it: a single degenerate step's wrong rate
(issue 11's random-outdoor at 2 cm, 2 deg off, held over 11 bridged epochs) is outvoted.
``robust`` bridges with a Kalman filter's rate at the last measured step, each step
weighed by its stated variance (:mod:`planodom.odometry.bridge_robust`).
The velocity stays the prediction's. With ``odometry.bridge_normals`` the bridge's rotation
is then corrected by the normals the epoch shares with its reference
(:mod:`.bridge_normals`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from planodom.config import OdometryConfig, PlanodomConfig
from planodom.geometry import twist_step
from planodom.odometry.bridge_normals import normals_bridged
from planodom.odometry.bridge_robust import robust_twist
from planodom.odometry.trend import trend_twist
from planodom.planes import PlaneSet

if TYPE_CHECKING:
    from planodom.odometry.twist_sigma import TwistUncertainty

#: Fewest measured rates the trend is fit to (a slope and its residuals' variance).
MIN_RATES = 4

#: Fewest measured rates a median of more than that many is taken over.
MEDIAN_MIN_RATES = 3


def bridge_twist(
    twist: np.ndarray | None,
    rates: Sequence[tuple[int, np.ndarray]],
    k: int,
    config: OdometryConfig,
    variances: Sequence[np.ndarray] = (),
) -> np.ndarray | None:
    """(6,) the twist (rad/s, m/s) an unresolved epoch ``k`` is bridged with: ``twist``
    (the prediction; None: none) with ``config.bridge_rate`` "last", or before
    :data:`MIN_RATES` of ``rates`` ((epoch, own twist (6,)) of the recent epochs that
    measured their rate, oldest first, each the mean over its step); with "trend" its
    angular rate extrapolated along their trend to epoch ``min(k, last + bridge_trend_
    epochs)``; with "median" see :func:`median_twist`; with "robust" (``variances``: the
    rates' stated variances (3,) each) :func:`planodom.odometry.bridge_robust.robust_twist`."""
    if twist is None or config.bridge_rate == "last":
        return twist
    if config.bridge_rate == "robust":
        return robust_twist(twist, rates, variances)
    if config.bridge_rate == "median":
        return median_twist(twist, rates, config.bridge_median_steps)
    if len(rates) < MIN_RATES:
        return twist
    x = np.array([j for j, _ in rates], dtype=float)
    at = min(float(k), x[-1] + config.bridge_trend_epochs)
    trend = trend_twist(np.array([tw for _, tw in rates]), x, at)
    return np.r_[trend[:3], twist[3:]]


def median_twist(twist: np.ndarray, rates: Sequence[tuple[int, np.ndarray]], n: int) -> np.ndarray:
    """(6,) ``twist`` (rad/s, m/s) with its angular rate replaced by the component-wise
    median of the angular rates of the last ``n`` of ``rates`` ((epoch, own twist (6,)),
    oldest first); ``twist`` itself while fewer than ``min(n, MEDIAN_MIN_RATES)`` are
    known (RANGEOUT's what-if in experiments/builtin_stretch.py asked for 3)."""
    if len(rates) < min(n, MEDIAN_MIN_RATES):
        return twist
    recent = np.array([tw[:3] for _, tw in list(rates)[-n:]], dtype=float)
    return np.r_[np.median(recent, axis=0), twist[3:]]


def bridge(
    prediction: np.ndarray | None,
    T_ref_last: np.ndarray,
    twist: np.ndarray | None,
    dt: float,
    rates: Sequence[tuple[int, np.ndarray]],
    k: int,
    config: OdometryConfig,
    variances: Sequence[np.ndarray] = (),
    walls: tuple[PlaneSet, PlaneSet, PlanodomConfig, TwistUncertainty | None] | None = None,
) -> np.ndarray:
    """(4, 4) ``T_{ref}_k`` an unresolved epoch ``k`` is bridged with: ``prediction``
    (``T_ref_last @ twist_step(twist, dt)``; None: none, e.g. across a gap, then
    ``T_ref_last`` (4, 4), standing still), or with ``bridge_rate`` trend, median or
    robust the same step made with :func:`bridge_twist` (``variances`` its); with
    ``walls`` (the reference's planes, the epoch's, the config, the run's twist
    uncertainty), its rotation corrected by their normals with ``odometry.bridge_normals``
    (:func:`.bridge_normals.normals_bridged`; ``weighed``: against the bridge's rotation
    sigma, :meth:`.twist_sigma.TwistUncertainty.bridged_rotation_sigma`)."""
    if prediction is None:
        return T_ref_last
    used = bridge_twist(twist, rates, k, config, variances)
    T = prediction if used is twist or used is None else T_ref_last @ twist_step(used, dt)
    if walls is None:
        return T
    prev, curr, cfg, uncertainty = walls
    variance = None
    if uncertainty is not None and cfg.odometry.bridge_normals == "weighed":
        variance = uncertainty.bridged_rotation_sigma(dt) ** 2 / 3
    return normals_bridged(T, prev, curr, cfg, variance)
