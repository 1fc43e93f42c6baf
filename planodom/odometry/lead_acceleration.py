"""A plane-map epoch deskewed with its rate's change too (``odometry.map_lead_acceleration``).

The deskewing's model is a constant twist over the sweep. Where the angular rate changes
within it (a turn's onset, peak and end), the points are rotated by ``alpha t^2 / 2`` off
that model (``alpha`` the angular acceleration, ``t`` the point's time from the sweep's
reference time). Each epoch's registration then carries an offset that follows
``alpha``; over a turn these offsets cancel step by step only while every sweep is
deskewed with its own constant twist. With the led rate (``odometry.map_twist_lead``)
that is not so at a turn's peak, where the lead overshoots (LIDAR9, docs/RESULTS.md).

With the option on, the points of an epoch whose rate is led are first rotated by
``exp(alpha t^2 / 2)`` about their reference time, then deskewed with the twist as
always: second order in ``t`` (the two rotations' commutator is third order).
``alpha`` is the rate's change per second from the twist the previous epoch was kept
with to the one this extraction is given (both led to their sweep's middle); with
"stated", each axis of that change shrunk by its Wiener gain (:func:`.trend.shrunk_lead`),
its noise :data:`LED_CHANGE_VARIANCE` times the previous step's stated rate variance.
Only the rotation: the linear velocity stays constant over the sweep.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from planodom.config import OdometryConfig
from planodom.odometry.kept_epoch import KeptEpoch
from planodom.odometry.trend import Lead, shrunk_lead
from planodom.scan import Scan

#: The variance of two successive led rates' difference over one step's rate variance:
#: ``led_k = 1.5 own_k - 0.5 own_{k-1}``, so ``led_k - led_{k-1} = 1.5 own_k - 2 own_{k-1} +
#: 0.5 own_{k-2}``, ``1.5^2 + 2^2 + 0.5^2`` for independent steps of equal variance.
LED_CHANGE_VARIANCE = 6.5


@dataclass(frozen=True)
class LeadAcceleration:
    """How one epoch's ``scan`` is rotated before it is deskewed: ``previous`` (6,), the
    twist the epoch before was kept with (rad/s, m/s), ``dt`` seconds between them."""

    scan: Scan
    previous: np.ndarray
    dt: float
    variance: np.ndarray | None = None

    def accelerated(self, scan: Scan, twist: np.ndarray | None) -> Scan:
        """``scan`` with its points rotated by ``exp(alpha t^2 / 2)``, ``alpha = (twist -
        previous)[:3] / dt`` (:func:`accelerated_points`); ``scan`` as it is when it is
        not this epoch's (a reference extracted again), without times or ``twist``."""
        if scan is not self.scan or twist is None or scan.t is None:
            return scan
        change = np.asarray(twist, dtype=np.float64)[:3] - self.previous[:3]
        if self.variance is not None:  # "stated": each axis shrunk by its noise
            change = shrunk_lead(change, change, LED_CHANGE_VARIANCE * self.variance)
        alpha = change / self.dt
        return replace(scan, points=accelerated_points(scan.points, scan.t, alpha))


def accelerated_points(points: np.ndarray, t: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """(N, 3) ``points`` (N, 3), each rotated by ``exp(alpha t_i^2 / 2)`` (Rodrigues about
    the fixed axis ``alpha / |alpha|``), ``t`` (N,) seconds from the reference time,
    ``alpha`` (3,) rad/s^2."""
    a = float(np.linalg.norm(alpha))
    if a == 0.0 or not np.isfinite(a):
        return np.array(points, dtype=np.float64, copy=True)
    k = alpha / a
    angle = (a * np.asarray(t, dtype=np.float64) ** 2 / 2)[:, None]
    p = np.asarray(points, dtype=np.float64)
    kxp = np.cross(k, p)
    return p * np.cos(angle) + kxp * np.sin(angle) + np.outer(p @ k, k) * (1 - np.cos(angle))


def lead_acceleration(
    lead: Lead | None, scan: Scan, history: Sequence[KeptEpoch], dt: float,
    config: OdometryConfig,
) -> LeadAcceleration | None:  # fmt: skip
    """How epoch ``scan`` is rotated before it is deskewed (``config.map_lead_acceleration``;
    None when off): only where its rate is led (``lead`` with the previous epoch's rate)
    and the epoch before (the last of ``history``) was deskewed with a twist."""
    if config.map_lead_acceleration == "off" or lead is None or lead.previous is None:
        return None
    if not history or history[-1].twist is None or not dt > 0:
        return None
    stated = config.map_lead_acceleration == "stated" and lead.previous_var is not None
    variance = np.asarray(lead.previous_var, dtype=np.float64) if stated else None
    return LeadAcceleration(scan, np.asarray(history[-1].twist, dtype=np.float64), dt, variance)
