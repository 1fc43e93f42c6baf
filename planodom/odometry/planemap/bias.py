"""The laser bias fitted to a scan's registration residuals (``planemap.laser_bias: fitted``).

The registration's model variance of each moment residual (:mod:`.moments`,
:func:`.outliers.whitened`) is the point noise plus a per-laser range bias ``b`` constant
along a scan line, in the scan's plane and in the landmark it is matched to::

    v = sigma^2 + b^2 N / rows  +  (landmark: its offset and normal variances, both
                                    sigma^2 / ... + b^2 / ... terms)

and every part is linear in ``b^2``: ``v = A + b^2 B`` per residual. The bias decides the
planes' relative weights (with ``b = 0`` a plane's information grows with its points,
with a large one with its scan lines), while the scan's residual scale
(:func:`.outliers.residual_scale`) only scales them all. A fixed ``b`` (the datasheet's 2
cm) is right for a lidar whose lasers carry such biases and, on a recording, absorbs other
model errors (map lag, scan skew) too; on a lidar without biases it weights a plane of 2000
points over 20 lines as 20 points and throws away most of what the scan measures. Fitted,
``b`` is the value at which the associations' median mean squared whitened residual (the
offset and the two tilts, as the residual scale and the Cauchy kernel read them) equals
its median under a right model (chi-square with 3 DoF, over 3): variance-component
estimation by the median, robust to the few outliers the kernel leaves. Between 0 and
``planemap.laser_bias_m`` (an upper bound then: beyond it the residual scale inflates all
variances alike, as with the fixed bias). The registration of one scan uses the bias fitted
to the scan before (the map's variances are refit with it, :func:`.landmarks.update_map`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planodom.median import median
from planodom.odometry.planemap.landmarks import PlaneMap
from planodom.odometry.planemap.moments import moment_residuals
from planodom.odometry.planemap.outliers import MEDIAN_CHI2_3, TESTED

if TYPE_CHECKING:
    from planodom.odometry.planemap.register import ScanPlanes

#: Fewest inlier associations a bias is fitted to (a median of fewer says little).
MIN_ASSOCIATIONS = 6
#: Bisection steps on ``b`` (the interval shrinks 2^-40: far below any noise).
_STEPS = 40


def variance_parts(
    M: PlaneMap, T: np.ndarray, cur: ScanPlanes, lm: np.ndarray, jj: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Residuals ``r`` (m, 4) of the associations (scan planes ``jj`` (m,) -> landmarks
    ``lm`` (m,)) under ``T`` (4, 4, world from scan) and their variances as ``A + b^2 B``:
    ``A`` (m, 4) m^2, ``B`` (m, 4) (module docstring)."""
    R, t = T[:3, :3], T[:3, 3]
    N, c, lam, E = cur.m.N[jj], cur.m.c[jj], cur.lam[jj], cur.E[jj]
    r, _, U = moment_residuals(R, t, M.n[lm], M.d[lm], N, c, lam, E)
    b0 = M.bias_m**2
    Cb, vob = M.cov_n_bias[lm], M.var_o_bias[lm]
    C0, vo0 = M.cov_n[lm] - b0 * Cb, M.var_o[lm] - b0 * vob
    dx = c @ R.T + t - M.c[lm]
    per_line = N / np.maximum(cur.m.rows[jj], 1.0)
    sigma2 = cur.sigma**2
    A, B = np.empty_like(r), np.empty_like(r)
    A[:, 0] = sigma2 + N * (np.einsum("mi,mij,mj->m", dx, C0, dx) + vo0)
    B[:, 0] = per_line + N * (np.einsum("mi,mij,mj->m", dx, Cb, dx) + vob)
    A[:, 1:] = sigma2 + lam * np.einsum("mak,mab,mbk->mk", U, C0, U)
    B[:, 1:] = per_line[:, None] + lam * np.einsum("mak,mab,mbk->mk", U, Cb, U)
    if cur.deskew is not None:
        A += cur.deskew[jj]
    return r, np.maximum(A, 1e-3 * sigma2), np.maximum(B, 0.0)


def median_chi2(r: np.ndarray, A: np.ndarray, B: np.ndarray, b: float) -> float:
    """Median over the associations of the mean squared whitened residual (offset and
    tilts) with the bias ``b`` (m)."""
    v = A[:, TESTED] + b**2 * B[:, TESTED]
    return median(np.sum(r[:, TESTED] ** 2 / v, axis=1) / 3.0)


def fitted_bias(
    M: PlaneMap, T: np.ndarray, cur: ScanPlanes, lm: np.ndarray, jj: np.ndarray, upper_m: float
) -> float | None:
    """The laser bias (m) in ``[0, upper_m]`` that makes the associations' median mean
    squared whitened residual that of a right model (module docstring), by bisection;
    None with fewer than :data:`MIN_ASSOCIATIONS` associations."""
    if len(lm) < MIN_ASSOCIATIONS or len(M) == 0:
        return None
    r, A, B = variance_parts(M, T, cur, lm, jj)
    if median_chi2(r, A, B, 0.0) <= MEDIAN_CHI2_3:
        return 0.0
    if median_chi2(r, A, B, upper_m) >= MEDIAN_CHI2_3:
        return upper_m
    lo, hi = 0.0, upper_m
    for _ in range(_STEPS):
        mid = 0.5 * (lo + hi)
        if median_chi2(r, A, B, mid) > MEDIAN_CHI2_3:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)
