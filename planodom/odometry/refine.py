"""Weighted least squares over all associated planes, after the consensus (beyond the paper).

The consensus (:mod:`planodom.consensus`) keeps one candidate: one pair's rotation and one
pair's reference point, so the other planes only vote. Once the associations are known
(SDA under the consensus pose), every associated plane measures the motion, as in the
oracle (:mod:`planodom.oracle`):

- rotation: the weighted orthogonal Procrustes fit of the previous normals to the rotated
  current ones (``scipy.spatial.transform.Rotation.align_vectors``), weights the inverse
  variance of each association's normals;
- translation: with ``p_prev = R p_curr + t`` a plane association ``(i, j)`` gives
  ``m . t = d_j - d_i`` (``m`` the mean of ``n_i`` and ``R n_j``): a linear equation,
  weighted by the inverse variance of ``d_i - d_j + m . t`` propagated from both planes'
  ``(n, d)`` covariances, plus ``offset_floor_m`` squared for what a fit's covariance does
  not hold (deskewing, a plane's bend).

No pair has to cut at a large angle: walls a few degrees apart in yaw measure the
horizontal translation together, and the normal matrix says how well. A horizontal
direction counts as measured when its standard deviation is at most ``max_sigma_m``. The
initial value (the consensus's or the prior's) enters as a prior as wide as the motion
bound: a direction the planes hardly measure stays near it, and a corridor still
measures its cross-track offset (the epoch is then degenerate). The vertical is solved
jointly when an up-facing, near-horizontal plane (the ground) is associated, else it
keeps its initial value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from planodom.planes import PlaneSet

#: Fallback (n, d) variances when a plane's covariance is unknown: 1 deg, 1 cm.
_FALLBACK_VAR_N, _FALLBACK_VAR_D = np.radians(1.0) ** 2, 0.01**2


@dataclass(frozen=True, eq=False)
class PlaneTranslation:
    """Result of :func:`plane_translation`.

    Attributes:
        t: (3,) translation of ``T_prev_curr``, m.
        cov_xy: (2, 2) covariance of its horizontal part, m^2 (the initial value's
            directions that were not measured get ``unmeasured_var``).
        sigma_z: m (inf when not observed). z_observed: the ground was associated.
        measured: every horizontal direction measured (at most ``max_sigma_m``).
        n_planes: associations used.
    """

    t: np.ndarray
    cov_xy: np.ndarray
    sigma_z: float
    z_observed: bool
    measured: bool
    n_planes: int


def _offset_variances(
    prev: PlaneSet, curr: PlaneSet, R: np.ndarray, ij: np.ndarray, t: np.ndarray
) -> np.ndarray:
    """(L,) variance of ``d_i - d_j + m . t`` per association, first order, m^2."""
    i, j = ij[:, 0], ij[:, 1]
    a_i = np.append(0.5 * t, 1.0)  # np.r_ costs more than this function's arithmetic
    a_j = np.append(0.5 * (R.T @ t), -1.0)
    ci, cj = prev.covariances[i], curr.covariances[j]
    fallback = _FALLBACK_VAR_N * float(t @ t) / 2.0 + 2.0 * _FALLBACK_VAR_D
    var = np.einsum("a,lab,b->l", a_i, ci, a_i) + np.einsum("a,lab,b->l", a_j, cj, a_j)
    return np.where(np.isfinite(var), var, fallback)


def plane_translation(
    prev: PlaneSet,
    curr: PlaneSet,
    R: np.ndarray,
    ij: np.ndarray,
    t0: np.ndarray,
    z_normal_min: float | None,
    offset_floor_m: float,
    max_sigma_m: float,
    unmeasured_var: float,
    consensus_measured: bool = False,
) -> PlaneTranslation:
    """Translation by weighted least squares over the plane associations ``ij`` (L, 2).

    Args:
        R: (3, 3) ``R_prev_curr``. t0: (3,) initial translation, m.
        z_normal_min: associations whose previous normal has ``n_z`` at least this are
            ground-like and let z be solved; None: z is not estimated.
        offset_floor_m: added (squared) to every association's offset variance, m.
        max_sigma_m: largest standard deviation of a measured horizontal direction, m.
        unmeasured_var: variance of ``t0``'s horizontal part, m^2 (a prior: the planes
            move the weak directions only as far as they measure them).
        consensus_measured: the consensus measured the translation; it decides when a
            plane's covariance is unknown (then the fallback variances are guesses).
    """
    t0 = np.asarray(t0, dtype=np.float64)
    if len(ij) == 0:
        return PlaneTranslation(t0.copy(), np.eye(2) * unmeasured_var, np.inf, False, False, 0)
    m = prev.normals[ij[:, 0]] + curr.normals[ij[:, 1]] @ R.T
    m /= np.linalg.norm(m, axis=1, keepdims=True)
    b = curr.offsets[ij[:, 1]] - prev.offsets[ij[:, 0]]
    w = 1.0 / (_offset_variances(prev, curr, R, ij, t0) + offset_floor_m**2)
    keep = _inliers(m, b, w, t0, z_normal_min)
    ij, m, b, w = ij[keep], m[keep], b[keep], w[keep]
    z_observed = z_normal_min is not None and bool(np.any(m[:, 2] >= z_normal_min))
    A = np.einsum("l,li,lj->ij", w, m, m)
    # Horizontal information: the Schur complement of z when z is solved, else A_xy.
    A_xy = A[:2, :2] - np.outer(A[:2, 2], A[2, :2]) / A[2, 2] if z_observed else A[:2, :2]
    lam = np.linalg.eigvalsh(A_xy)
    measured = bool(lam[0] * max_sigma_m**2 >= 1.0)
    i, j = ij[:, 0], ij[:, 1]
    if not (np.isfinite(prev.covariances[i]).all() and np.isfinite(curr.covariances[j]).all()):
        # Without the fits' covariances the precision is a guess: the consensus decides.
        measured = (measured or consensus_measured) and lam[0] > 1e-9 * lam[1]
    free = 3 if z_observed else 2
    # Unless the planes measure every direction, the initial value is a prior of
    # variance ``unmeasured_var`` on x, y: what keeps an unmeasured direction where it was
    # (when they do, it is left out: noise-free planes give the exact translation).
    prior = 0.0 if measured else 1.0 / unmeasured_var
    H = A[:free, :free] + np.diag([prior] * 2 + [0.0] * (free - 2))
    g = m[:, :free].T @ (w * (b - m @ t0))
    H_inv = np.linalg.inv(H)
    t = t0.copy()
    t[:free] += H_inv @ g
    sigma_z = float(np.sqrt(H_inv[2, 2])) if z_observed else np.inf
    return PlaneTranslation(t, H_inv[:2, :2], sigma_z, z_observed, measured, len(ij))


#: chi2(1) at 0.999: an association whose offset residual is beyond this (in its own
#: sigmas) after the others are fitted is not kept.
_OUTLIER_CHI2 = 10.83


def _inliers(
    m: np.ndarray, b: np.ndarray, w: np.ndarray, t0: np.ndarray, z_normal_min: float | None
) -> np.ndarray:
    """(L,) bool: the associations kept, dropping the worst one while its normalised
    residual ``w (b - m . t)^2`` exceeds :data:`_OUTLIER_CHI2` and three stay (a plane
    that was matched to a nearly coplanar neighbour, or fitted across two surfaces,
    would otherwise bias every direction it touches: on the noise-free paper loop one
    such association moved an epoch by 1.4 mm). Fitted as in :func:`plane_translation`,
    without a prior (a direction no kept plane measures keeps ``t0``)."""
    keep = np.ones(len(b), dtype=bool)
    free = 3 if z_normal_min is not None and np.any(m[:, 2] >= z_normal_min) else 2
    while keep.sum() > 3:
        mk, wk = m[keep, :free], w[keep]
        t = t0.copy()
        t[:free] += np.linalg.lstsq(
            mk * np.sqrt(wk)[:, None], np.sqrt(wk) * (b[keep] - m[keep] @ t0), rcond=1e-9
        )[0]
        e2 = w * (b - m @ t) ** 2
        worst = int(np.argmax(np.where(keep, e2, -1.0)))
        if e2[worst] <= _OUTLIER_CHI2:
            break
        keep[worst] = False
    return keep


def plane_rotation(
    prev: PlaneSet,
    curr: PlaneSet,
    R: np.ndarray,
    ij: np.ndarray,
    normal_floor: float,
    min_angle: float,
) -> np.ndarray:
    """``R_prev_curr`` (3, 3) fitting the normals of the associations ``ij`` (L, 2) by
    weighted Procrustes (closed form); ``R`` when no two previous normals are ``min_angle``
    rad or more apart (the rotation about their direction would be unobserved).

    Weights: inverse of each association's normal variance (mean over the tangent axes,
    both planes) plus ``normal_floor`` rad squared.
    """
    if len(ij) < 2:
        return R
    n_p, n_c = prev.normals[ij[:, 0]], curr.normals[ij[:, 1]]
    # Two unit vectors theta apart: singular values of [n1 n2]^T / sqrt(2) are
    # cos(theta / 2) and sin(theta / 2).
    s = np.linalg.svd(n_p / np.sqrt(len(n_p)), compute_uv=False)
    if s[1] < np.sin(min_angle / 2.0):
        return R
    var = (
        np.trace(prev.covariances[ij[:, 0], :3, :3], axis1=1, axis2=2)
        + np.trace(curr.covariances[ij[:, 1], :3, :3], axis1=1, axis2=2)
    ) / 2.0
    var = np.where(np.isfinite(var), var, 2.0 * _FALLBACK_VAR_N)
    rot, _ = Rotation.align_vectors(n_p, n_c, weights=1.0 / (var + normal_floor**2))
    return rot.as_matrix()
