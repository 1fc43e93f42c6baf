"""The rotation of the refinement (:mod:`planodom.odometry.refine`): a weighted Procrustes
fit of the associated normals, and the normal variances that weigh it (split from
:mod:`planodom.odometry.refine`, which re-exports them)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from planodom.planes import PlaneSet

#: Fallback (n, d) variances when a plane's covariance is unknown: 1 deg, 1 cm.
_FALLBACK_VAR_N, _FALLBACK_VAR_D = np.radians(1.0) ** 2, 0.01**2


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
    var = normal_variances(prev.covariances[ij[:, 0]], curr.covariances[ij[:, 1]])
    rot, _ = Rotation.align_vectors(n_p, n_c, weights=1.0 / (var + normal_floor**2))
    return rot.as_matrix()


def normal_variances(prev_cov: np.ndarray, curr_cov: np.ndarray) -> np.ndarray:
    """(...,) variance, rad^2, of a normal association's residual along one tangent axis:
    the traces of both planes' normal blocks of the ``(n, d)`` covariances (..., 4, 4),
    summed and halved (a unit normal's covariance lies in its 2-D tangent plane); unknown
    (NaN) covariances count 1 deg per plane."""
    var = (
        np.trace(prev_cov[..., :3, :3], axis1=-2, axis2=-1)
        + np.trace(curr_cov[..., :3, :3], axis1=-2, axis2=-1)
    ) / 2.0
    return np.where(np.isfinite(var), var, 2.0 * _FALLBACK_VAR_N)
