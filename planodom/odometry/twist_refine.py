"""The twist an epoch is extracted again with (:func:`planodom.odometry.deskew.
register_deskewed`, step 2): its own twist with the blocks its step did not measure set to
zero (its rate weighed against the prediction with ``odometry.twist_blend``), refined
against the twist used by the tolerances, the rate along the secant, gated by the step's
error. Split from :mod:`planodom.odometry.deskew`, which uses it."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from scipy.stats import chi2

from planodom.config import OdometryConfig
from planodom.geometry import vector_norm
from planodom.odometry.change_gate import significant_change
from planodom.odometry.deskew_secant import solved_rate
from planodom.odometry.relative import RelativePose

if TYPE_CHECKING:
    from planodom.odometry.centred_twist import Centring
    from planodom.odometry.deskew import EpochEstimate
    from planodom.odometry.trend import Lead

#: ``blend(own, relative, dt) -> own``: an epoch's own twist (6,) over its step ``relative``
#: of ``dt`` s with its rate weighed against the prediction (:mod:`.twist_blend`).
Blend = Callable[[np.ndarray, RelativePose, float], np.ndarray]


def next_twist(
    own: np.ndarray,
    used: np.ndarray,
    measured: bool,
    config: OdometryConfig,
    lead: Lead | None,
    before: tuple[np.ndarray, np.ndarray] | None,
    relative: RelativePose,
    dt: float,
) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """The (6,) twist to extract the epoch with next, and the (used, own) pair the next
    refinement's secant starts from: the own twist refined (:func:`refined_twist`), its
    rate along the secant (``odometry.deskew_rate_solve``), then kept only where it differs
    beyond the step's error (``odometry.deskew_change_gate``)."""
    new = refined_twist(own, used, measured, config, lead)
    new = solved_rate(new, used, own, before, config)
    if config.deskew_change_gate:
        new = significant_change(new, used, relative, dt)
    return new, (used, own)


def refined_own(
    best: EpochEstimate,
    dt: float,
    used: np.ndarray,
    measured: bool,
    config: OdometryConfig,
    against_map: bool,
    lead: Lead | None,
    blend: Blend | None,
    centring: Centring | None = None,
) -> np.ndarray:
    """(6,) the own twist of ``best`` over ``dt`` s that step 2 refines the twist ``used``
    from (:func:`planodom.odometry.deskew.register_deskewed`): its rate weighed by
    ``blend`` (None: as it is), then :func:`significant_twist`, then, against a map,
    averaged with ``used`` (unless ``config.map_twist_offset``), or led by ``lead`` (its
    velocity only when ``measured``), or its rate led to the points by ``centring``
    (``odometry.deskew_rate_lead``, :mod:`.centred_twist`; None: not)."""
    own = best.own_twist(dt)
    own = own if blend is None else blend(own, best.relative, dt)
    own = significant_twist(own, best.relative, dt, config)
    if against_map and not config.map_twist_offset:
        return 0.5 * (own + used)
    if lead is not None:
        return lead.led(own, measured, dt, best.relative)
    return own if centring is None else centring.led_for(own, best)


def refined_twist(
    own: np.ndarray,
    used: np.ndarray,
    measured: bool,
    config: OdometryConfig,
    lead: Lead | None = None,
) -> np.ndarray:
    """The twist (6,) to extract again with: the epoch's ``own`` angular rate and (when its
    translation was ``measured``) linear velocity, each only where it differs from the
    twist ``used`` by more than its tolerance (``config``'s, or ``lead``'s); else ``used``
    unchanged. With the lead's vertical tolerance (``odometry.map_lead_vertical_
    tolerance_mps``) the vertical velocity is also taken alone beyond it."""
    rate_tol, speed_tol = config.deskew_rate_tolerance_deg_s, config.deskew_speed_tolerance_mps
    if lead is not None:
        rate_tol, speed_tol = lead.rate_tolerance_deg_s, lead.speed_tolerance_mps
    new = used.copy()
    if np.degrees(vector_norm(own[:3] - used[:3])) > rate_tol:
        new[:3] = own[:3]
    if measured and vector_norm(own[3:] - used[3:]) > speed_tol:
        new[3:] = own[3:]
    vertical = None if lead is None else lead.vertical_tolerance_mps
    if measured and vertical is not None and abs(own[5] - used[5]) > vertical:
        new[5] = own[5]  # a floor seen across the sweep's seam tilts with it (LIDAR13)
    return new


def significant_twist(
    twist: np.ndarray, relative: RelativePose, dt: float, config: OdometryConfig
) -> np.ndarray:
    """(6,) ``twist`` (rad/s, m/s) of a step of ``dt`` seconds with the blocks its step
    did not measure beyond noise set to zero (``config.deskew_significance_gate``; else
    ``twist`` as it is): the rotation ``twist[:3] dt`` when within the chi-square 95 %
    bound (3 DoF) of zero given the rotation block of ``relative.covariance``, the linear
    velocity when its horizontal step ``twist[3:5] dt`` is within the bound (2 DoF) of the
    (x, y) block (the vertical is not in the covariance and goes with it). A parked
    lidar's step is noise, and deskewing with it moves the next extraction by it: only a
    twist told apart from zero is a motion."""
    cov = relative.covariance
    if not config.deskew_significance_gate or cov is None or dt <= 0:
        return twist
    out = np.array(twist, dtype=np.float64, copy=True)
    for block, dims in ((slice(0, 3), slice(0, 3)), (slice(3, 6), slice(3, 5))):
        step = out[dims] * dt
        c = np.asarray(cov)[dims, dims]
        m2 = float(step @ np.linalg.pinv(c) @ step) if np.all(np.isfinite(c)) else 0.0
        if m2 <= _CHI2_95[len(step)]:
            out[block] = 0.0
    return out


#: chi-square 95 % quantiles by degrees of freedom (scipy.stats.chi2.ppf(0.95, k)).
_CHI2_95 = {2: float(chi2.ppf(0.95, 2)), 3: float(chi2.ppf(0.95, 3))}
