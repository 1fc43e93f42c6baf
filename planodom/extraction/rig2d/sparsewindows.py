"""A time window's plane of few points kept only where its points determine it.

With ``extraction.time_windows.min_points_over_windows`` a window's plane needs only a
share of ``min_plane_points`` (:func:`.windows.per_window`). How well a few points fix a
plane depends on the noise and on where the points lie: a sweep's seven points on two
short traces give a wall's normal to a fraction of a degree at 6 mm and to about a
degree at 2 cm, and the offset at the base origin of a wall seen far along it (a lever
arm of tens of metres on that angle) only to decimetres (issue 11's world 6 at 2 cm: a
wall kept 94 cm off, docs/RESULTS.md, GAPS3). With
``time_windows.sparse_windows_determined`` such a plane (fewer than
``min_plane_points`` inliers) is kept, and counts as one of a wall's windows, only
when its fit determines it as a plane must be known (:func:`determined`): its normal
to ``extraction.max_normal_sigma_deg`` and its offset to the member tolerance
(:func:`planodom.extraction.noise.member_tolerance`), the distance within which a point
belongs to a plane.

The sigmas are the TLS fit's (:func:`planodom.extraction.planes.fit.tls_covariance`)
with the residual sigma floored at the epoch's noise sigma. The fit's own residual says
little with a handful of points (its chi-square has N - 3 degrees of freedom, two to
five here), and a chance coincidence of two traces is the case where it is small by
construction: the traces were grouped because they fit.
"""

from __future__ import annotations

import numpy as np

from planodom.extraction.planes.builder import PlaneFits
from planodom.extraction.planes.fit import tls_covariance


def plane_sigmas(fits: PlaneFits, sigma_m: float) -> tuple[np.ndarray, np.ndarray]:
    """(G,) 1-sigma errors of each fit's normal (rad, ``sqrt(trace Cov(n))``) and offset
    (m, at the base origin) with a point noise across the plane of ``max(sigma_m,
    sqrt(l3 / (N - 3)))`` (m); infinite where the points do not span a plane."""
    with np.errstate(divide="ignore", invalid="ignore"):
        cov = tls_covariance(fits.evals, fits.evecs, fits.centroid, fits.count, sigma_m)
        var_n = np.trace(cov[:, :3, :3], axis1=1, axis2=2)
        var_d = cov[:, 3, 3]
    ok = np.isfinite(var_n) & np.isfinite(var_d)
    return (
        np.sqrt(np.where(ok, var_n, np.inf)),
        np.sqrt(np.where(ok, np.maximum(var_d, 0.0), np.inf)),
    )


def determined(
    fits: PlaneFits,
    sigma_m: float,
    min_plane_points: int,
    max_normal_sigma_deg: float,
    max_offset_sigma_m: float,
) -> np.ndarray:
    """(G,) bool: the fits a window may keep: those of at least ``min_plane_points``
    inliers, and the others whose :func:`plane_sigmas` at noise ``sigma_m`` (m) are at
    most ``max_normal_sigma_deg`` and ``max_offset_sigma_m`` (m)."""
    sig_n, sig_d = plane_sigmas(fits, sigma_m)
    ok = (sig_n <= np.radians(max_normal_sigma_deg)) & (sig_d <= max_offset_sigma_m)
    return (fits.count >= min_plane_points) | ok
