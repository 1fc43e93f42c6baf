"""The variance of a plane-map epoch's led twist, in closed form (``planemap.lead_weights``).

With ``odometry.map_twist_lead`` an epoch registered at its sweep's middle is extracted
again with its own twist ``o`` (the mean over its step, half an epoch behind the sweep's
middle) led along its change since the previous epoch's ``p``: ``o + g k (o - p)``, ``k =
dt / (dt + dt_prev)`` (:func:`planodom.odometry.trend.led_twist`), ``g`` the Wiener gain of
``odometry.map_lead_shrink`` (1 unshrunk, 0 where not led: the velocity under ``rate``).
With ``o`` and ``p`` carrying independent errors of variances ``v_o``, ``v_p`` (the steps'
stated ones) and the true rate changing linearly (the lead exact), the led twist's error
against the rate at the sweep's middle is ``(1 + g k) e_o - g k e_p - (1 - g) k c``,
``c`` the true change, so per axis::

    var = (1 + g k)^2 v_o + (g k)^2 v_p + ((1 - g) k)^2 max(c_m^2 - v_o - v_p, 0)

with the measured change ``c_m`` (``E c_m^2 = c^2 + v_o + v_p``). The twist an epoch is
extracted with may differ from the lead by less than the re-extraction tolerances (then it
was kept): that known gap is added squared. The planes' variances follow through their
deskewing Jacobians (:mod:`planodom.odometry.planemap.deskew_weights`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planodom.odometry.bridge_robust import rate_variance
from planodom.odometry.deskew import centred_times
from planodom.odometry.plane_deskew import epoch_span
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.trend import map_lead
from planodom.odometry.twist_refine import significant_twist
from planodom.scan import Scan

if TYPE_CHECKING:
    from planodom.odometry.deskew import EpochEstimate
    from planodom.odometry.odometry import PlaneOdometry


def lead_variance(
    v_own: np.ndarray, v_prev: np.ndarray, change: np.ndarray, k: float, gain: np.ndarray
) -> np.ndarray:
    """Per axis, the variance of ``own + gain k (own - previous)`` against the value at the
    lead's time (module docstring): ``own`` and ``previous`` of variances ``v_own``,
    ``v_prev``, measured ``change = own - previous``; all (n,) but ``k``."""
    unled = np.maximum(change**2 - v_own - v_prev, 0.0)
    gk = gain * k
    return (1.0 + gk) ** 2 * v_own + gk**2 * v_prev + ((1.0 - gain) * k) ** 2 * unled


def velocity_variance(relative: RelativePose | None, dt: float) -> np.ndarray:
    """(3,) the stated variance, (m/s)^2, of a step's velocity: its covariance's (x, y)
    diagonal over ``dt``^2, the vertical (not in the 5 x 5 covariance) their mean; NaN
    without a covariance or a positive ``dt``."""
    if relative is None or relative.covariance is None or not dt > 0:
        return np.full(3, np.nan)
    xy = np.diag(relative.covariance)[3:5] / dt**2
    return np.r_[xy, xy.mean()]


def led_variance(
    odo: PlaneOdometry,
    scan: Scan,
    t: float,
    twist: np.ndarray | None,
    source: EpochEstimate | None,
) -> tuple[np.ndarray, float] | None:
    """(the variance (6,) per axis, (rad/s)^2 and (m/s)^2, of the error of ``twist``, the
    twist the next epoch (at ``t``) of ``odo`` is extracted with, led from ``source``'s
    own; the scan's span ``max |t|``, s), or None when ``planemap.lead_weights`` is off or
    the twist is not led from a measured step (the first extraction, a gap, no plane map,
    no lead, no centred times, a variance not stated)."""
    config = odo.config
    k = len(odo.poses)
    if config.planemap.lead_weights == "off" or odo._map is None or not odo.times:
        return None
    if source is None or twist is None or k in odo._gaps:
        return None
    if config.planemap.reference_time != "middle" or not centred_times(scan):
        return None
    dt, ocfg = t - odo.times[-1], config.odometry
    lead = map_lead(odo._rates, k, odo.times, odo.results[-1], ocfg, odo._rate_vars)
    if lead is None or lead.previous is None or not dt > 0:
        return None
    measured = source.relative.status is Status.OK
    own = significant_twist(source.own_twist(dt), source.relative, dt, ocfg)
    led = lead.led(own, measured, dt, source.relative)
    k_lead = dt / (dt + lead.previous_dt)
    previous = np.array(odo._rates[-1][1], dtype=float)
    v_prev = np.asarray(odo._rate_vars[-1], dtype=float)
    v_own = rate_variance(source.relative, dt)
    change = own[:3] - previous[:3]
    gain = np.ones(3)
    if lead.previous_var is not None:  # map_lead_shrink: stated
        c2 = change**2
        gain = c2 / np.maximum(c2 + v_own + v_prev, 1e-300)
    rate = lead_variance(v_own, v_prev, change, k_lead, gain)
    vel_gain = (np.isfinite(lead.previous[3:]) & measured).astype(float)
    vv_prev = velocity_variance(odo.results[-1], lead.previous_dt)
    vv_own = velocity_variance(source.relative, dt)
    velocity = lead_variance(vv_own, vv_prev, own[3:] - previous[3:], k_lead, vel_gain)
    var = np.r_[rate, velocity] + (np.asarray(twist, dtype=float) - led) ** 2
    if not np.all(np.isfinite(var)):
        return None
    return var, epoch_span(scan)
