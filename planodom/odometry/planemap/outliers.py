"""Whitened moment residuals of the registration, and the leave-one-out test of its
associations (``planemap.outliers: deleted``).

An association is tested by its *deleted* residual: its residual under the pose the other
associations and the prediction give without it, against the variance of that residual
(its own noise plus the uncertainty of that pose where it falls). This is the classic
deleted (externally studentised) residual of least squares, with the prediction as a
prior: it needs no threshold of its own beyond the Cauchy kernel's outlier definition.
It separates the two cases the plain fitted residual confuses:

- a few associations that alone observe a direction pull the fit onto themselves, so their
  fitted residual along it is near zero whatever they are (on a parked lidar, fragments of
  curved surfaces that moved it 5-24 cm): without them that direction falls back to the
  prediction, and a wrong association disagrees with it by far more than the prediction's
  uncertainty;
- a true plane whose model is a little off (a cambered road) disagrees with the rest by a
  few of its model sigmas, but its deleted residual is measured against a pose that the
  others determine only loosely in the directions it observes: the variance grows with
  what it alone brings, and it is kept (down-weighted by the kernel) instead of dropped.

The test is linearised at the converged pose (one Gauss-Newton step of the problem without
the association, from the solution with it): an association's removal changes the pose by
its pull, ``H_(-i)^-1 w_i J_i^T e_i``, in closed form for all associations at once.
"""

from __future__ import annotations

import numpy as np

from planodom.median import median
from planodom.odometry.planemap.landmarks import PlaneMap
from planodom.odometry.planemap.moments import moment_residuals
from planodom.rotvec import rotation_vectors

#: Median of a chi-square variable with 3 degrees of freedom, divided by 3: the median of
#: an association's mean squared whitened residual (offset and two tilts) when its model
#: variances are right (scipy.stats.chi2.median(3) / 3).
MEDIAN_CHI2_3 = 2.3659738843753377 / 3.0

#: The residuals that carry pose information and are tested: the offset and the two
#: tilts; the thickness residual (index 1) is the plane's own noise.
TESTED = np.array([0, 2, 3])


def residual_scale(chi2: np.ndarray) -> float:
    """The factor (at least 1) by which the associations' residuals (m,) mean squared
    whitened residuals ``chi2`` exceed their model variances, robustly: ``median(chi2)``
    over the median it has when the model is right. A scan whose planes all disagree more
    than their noise model says (a fast hand-held walk deskewed by a twist a few percent
    off, map lag) makes every plane less certain, not its best-measured planes outliers;
    the model variances are never shrunk."""
    if len(chi2) == 0:
        return 1.0
    return max(1.0, median(chi2) / MEDIAN_CHI2_3)


def whitened(
    M: PlaneMap,
    R: np.ndarray,
    t: np.ndarray,
    m_N: np.ndarray,
    m_c: np.ndarray,
    lam: np.ndarray,
    E: np.ndarray,
    s2: np.ndarray,
    lm: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Moment residuals of m associations under ``(R, t)``: ``r`` (m, 4), ``J`` (m, 4, 6),
    their variances ``v`` (m, 4) (the plane's noise ``s2``, (m,) for all four residuals
    alike or (m, 4) each its own, plus the landmark's
    uncertainty at the moved centroid / along the moved axes) and each association's mean
    squared whitened residual ``chi2`` (m,) over the offset and the two tilts."""
    r, J, U = moment_residuals(R, t, M.n[lm], M.d[lm], m_N, m_c, lam, E)
    x = m_c @ R.T + t
    v = np.empty_like(r)
    s_off, s_tilt = (s2[:, 0], s2[:, 1:]) if s2.ndim == 2 else (s2, s2[:, None])
    v[:, 0] = s_off + m_N * M.var_at(lm, x)
    v[:, 1:] = s_tilt + lam * np.einsum("mak,mab,mbk->mk", U, M.cov_n[lm], U)
    chi2 = np.sum(r[:, TESTED] ** 2 / v[:, TESTED], axis=1) / 3.0
    return r, J, v, chi2


def deleted_chi2(
    r: np.ndarray,
    J: np.ndarray,
    v: np.ndarray,
    w: np.ndarray,
    dev: np.ndarray,
    prior_info: np.ndarray,
) -> np.ndarray:
    """(m,) each association's deleted chi-square (3 DoF: offset and two tilts).

    Args:
        r, J, v: residuals (m, 4), Jacobians (m, 4, 6) and variances (m, 4) at the
            converged pose, the variances already scaled by the scan's residual scale.
        w: (m,) the Cauchy weights the pose was solved with.
        dev: (6,) the pose minus the prediction (rotation vector, translation), in the
            perturbation ``R <- exp(w) R, t <- t + dt``.
        prior_info: (6,) the prediction's information per axis (1/rad^2, 1/m^2).

    Per association i, with whitened ``e = r / sqrt(v)``, ``A = J / sqrt(v)``: the pose
    without it is one Newton step ``dx = -H_i^-1 g_i`` of ``H_i = sum_(k!=i) w_k A_k^T
    A_k + P``, ``g_i = sum_(k!=i) w_k A_k^T e_k + P dev``; its deleted residual ``e_i + A_i
    dx`` has the covariance ``I + A_i H_i^-1 A_i^T`` (its own noise, whitened, and the
    pose's uncertainty); the statistic is that residual's squared Mahalanobis length.
    """
    s = np.sqrt(v)
    e, A = r / s, J / s[:, :, None]
    WA = w[:, None, None] * A
    Hk = np.einsum("mki,mkj->mij", WA, A)  # each association's information
    gk = np.einsum("mki,mk->mi", WA, e)
    P = np.diag(prior_info)
    H_i = Hk.sum(axis=0)[None] - Hk + P[None]
    g_i = gk.sum(axis=0)[None] - gk + (P @ dev)[None]
    # H_i is positive definite (the prior): Cholesky-based solves stay well conditioned
    # with scaled columns (rotation in rad, translation in m, lever arms of metres)
    Ht = A[:, TESTED]  # (m, 3, 6)
    sol = np.linalg.solve(H_i, np.concatenate([g_i[:, :, None], np.swapaxes(Ht, 1, 2)], axis=2))
    step, HiAt = -sol[:, :, 0], sol[:, :, 1:]
    e_del = e[:, TESTED] + np.einsum("mki,mi->mk", Ht, step)
    C = np.eye(3)[None] + np.einsum("mki,mil->mkl", Ht, HiAt)
    return np.einsum("mk,mk->m", e_del, np.linalg.solve(C, e_del[:, :, None])[:, :, 0])


def pose_deviation(T: np.ndarray, T_pred: np.ndarray) -> np.ndarray:
    """(6,) ``T`` minus ``T_pred`` in the registration's perturbation ``R <- exp(w) R,
    t <- t + dt``: the rotation vector of ``R R_pred^T`` and ``t - t_pred``."""
    rot = rotation_vectors((T[:3, :3] @ T_pred[:3, :3].T)[None])[0]
    return np.r_[rot, T[:3, 3] - T_pred[:3, 3]]
