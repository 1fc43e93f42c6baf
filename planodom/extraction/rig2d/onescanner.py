"""One scanner's planes weighed by what they measure: their covariance widened by the twist.

A plane of one scanner's lines of several sweeps (:mod:`.sweeplines`) is spanned by
parallel lines displaced across each other by the motion between the sweeps, which the
deskewing removes: its tilt about the lines is the deskewing twist's, not the wall's. Its
fit covariance (:func:`planodom.extraction.planes.fit.fit_arrays`) holds the range noise
only and says the tilt is known to a few hundredths of a degree, so the consensus and the
solver trust it there as much as a plane of two crossing scanners.

With ``extraction.single_scanner_rate_sigma_deg_s`` (and ``..._speed_sigma_mps``) above 0,
every plane of a deskewed epoch whose inliers come from one ring (``PlaneSupport.n_rows``
1) gets, on top of its fit covariance, the first-order effect of a twist error of those
sigmas (isotropic, per axis): ``J diag(s_w^2 I, s_v^2 I) J^T``, with ``J`` (4, 6) the
change of the plane's ``(n, d)`` with the deskewing twist
(:func:`planodom.extraction.planes.fit.deskew_jacobian`, the points' times in seconds so
that ``J`` is per rad/s and m/s). That term is large for the tilt about the lines (a wall
at range r, lines of sweeps ``dt`` apart: ``s_w r dt`` across a separation of about
``w r dt``) and small for the normal's component across the lines and the offset near
them, which the lines fix. The odometry keeps a plane whose normal sigma this takes above
``extraction.max_normal_sigma_deg`` out of the rotation and the consensus
(:mod:`planodom.odometry.rotation_planes`); the translation refinement
(:mod:`planodom.odometry.refine`) weighs its offset by the widened covariance.

Measured against the simulator's truth (world 6, epochs 51-54, and world 166, epochs
78-82, 6 mm, deskewed with the true twist plus 1 deg/s of yaw rate): such planes are
tilted by 4.5 and 7.6 deg (median); the tilt's 2-DoF NEES is 744 and 1872 (median) with
the fit's covariance, 1.1 (1 deg/s, 0.2 m/s) and 2.4 (0.5 deg/s, 0.5 m/s) widened.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction.epoch import Epoch
from planodom.extraction.planes.fit import deskew_jacobian
from planodom.geometry import Plane


def twist_covariance(
    points: np.ndarray, t: np.ndarray, normal: np.ndarray, rate_sigma: float, speed_sigma: float
) -> np.ndarray:
    """(4, 4) covariance of a plane's ``(n, d)`` from a deskewing twist error of
    ``rate_sigma`` (rad/s) and ``speed_sigma`` (m/s) per axis, independent: the plane of
    ``points`` (K, 3) m, seen at ``t`` (K,) s after the reference time, unit ``normal``
    (3,) (module docstring)."""
    J = deskew_jacobian(points, t, normal)
    s2 = np.array([rate_sigma**2] * 3 + [speed_sigma**2] * 3)
    return (J * s2) @ J.T


def widened_planes(
    planes: list[Plane], inliers: list[np.ndarray], epoch: Epoch, config: ExtractionConfig
) -> list[Plane]:
    """``planes`` (with their ``inliers``, scan indices) with the one-ring planes'
    covariance widened (module docstring); the list unchanged when
    the option is off, the epoch has no twist or its points no times."""
    rate = float(np.radians(config.single_scanner_rate_sigma_deg_s))
    speed = float(config.single_scanner_speed_sigma_mps)
    t = epoch.scan.t
    if (rate == 0.0 and speed == 0.0) or epoch.twist is None or t is None:
        return planes
    out = []
    for plane, idx in zip(planes, inliers, strict=True):
        one_ring = plane.support is not None and plane.support.n_rows == 1
        if not one_ring or plane.covariance is None:
            out.append(plane)
            continue
        extra = twist_covariance(epoch.points[idx], t[idx], plane.normal, rate, speed)
        out.append(replace(plane, covariance=plane.covariance + extra))
    return out
