"""A time window's plane of few points kept only where its points determine it.

With ``extraction.time_windows.min_points_over_windows`` a window's plane needs only a
share of ``min_plane_points`` (:func:`.windows.per_window`). How well a few points fix a
plane depends on the noise: seven points of a sweep on two short crossing traces give a
wall's normal to a fraction of a degree at 6 mm and to several degrees at 2 cm, where two
sweeps' coincidences pass as walls (issue 11's phantoms, docs/RESULTS.md, GAPS). With
``time_windows.sparse_normal_sigma_deg`` such a plane (fewer than ``min_plane_points``
inliers) is kept only when its normal's 1-sigma error, from its points' spread and the
epoch's noise sigma, is at most that: :func:`determined`.

The error is the TLS fit's (:func:`planodom.extraction.planes.fit.tls_covariance`) with
the residual sigma replaced by the larger of it and the epoch's noise sigma. The fit's
own residual says little with a handful of points (its chi-square has N - 3 degrees of
freedom, two to five here), and a chance coincidence of two traces is the case where it
is small by construction: the traces were grouped because they fit.
"""

from __future__ import annotations

import numpy as np

from planodom.extraction.planes.builder import PlaneFits


def normal_sigma(fits: PlaneFits, sigma_m: float) -> np.ndarray:
    """(G,) 1-sigma error (rad, ``sqrt(trace Cov(n))``) of each fit's normal with a point
    noise of ``max(sigma_m, sqrt(l3 / (N - 3)))`` (m) across the plane: ``sigma^2 (l1 /
    (l1 - l3)^2 + l2 / (l2 - l3)^2)`` of the scatter eigenvalues l1 >= l2 >= l3 (m^2).
    Infinite where the points do not span a plane (l2 = l3)."""
    n = np.maximum(fits.count.astype(np.float64), 1.0)
    l1, l2, l3 = fits.evals[:, 0], fits.evals[:, 1], fits.evals[:, 2]
    s2 = np.maximum(sigma_m**2, l3 / np.maximum(n - 3.0, 1.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        var = s2 * (l1 / (l1 - l3) ** 2 + l2 / (l2 - l3) ** 2)
    return np.sqrt(np.where(np.isfinite(var), var, np.inf))


def determined(
    fits: PlaneFits, sigma_m: float, min_plane_points: int, max_sigma_deg: float | None
) -> np.ndarray | None:
    """(G,) bool: the fits a window may keep, those of at least ``min_plane_points``
    inliers and the others whose :func:`normal_sigma` at noise ``sigma_m`` (m) is at most
    ``max_sigma_deg``; None when ``max_sigma_deg`` is None (no test)."""
    if max_sigma_deg is None:
        return None
    full = fits.count >= min_plane_points
    return full | (normal_sigma(fits, sigma_m) <= np.radians(max_sigma_deg))
