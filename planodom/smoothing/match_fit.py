"""How well a match's own pose lays its associated planes on their old partners (issue 14).

A re-identification of full rank fits its pose to all its pairs. One of rotation only
(one wall and the ground, :mod:`planodom.smoothing.loops`) is verified on its yaw alone,
yet each of its ties also states where the pose lies along the tied wall's normal: that
translation is checked by nothing. On the 2D-rig world 2 at 6 mm, after the odometry's
failure bent the map by about 37 degrees, 19 of its 20 wrong ties came from such
matches, their walls 2.9 to 3.1 m off their old partners at the match's pose (a room's
wall tied to a parallel wall 4.9 m away). :func:`offset_residuals` measures that
residual, :func:`offset_statistic` weighs it against the drift of the predicted pose
(a fixed bound of 0.35 m refused 221 right matches on world 4 at 2 cm, where the chained
guess drifts further between matches, and its ATE rose 0.025 -> 0.126 m).

Written here, not taken from a library: a residual of the paper's plane association.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.geometry import Plane


def offset_residuals(
    old: Sequence[Plane],
    curr: Sequence[Plane],
    pairs: np.ndarray,
    T_old_curr: np.ndarray,
    default_sigma_m: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Offset residuals of the associated planes at the match's own pose.

    Args:
        old: planes of the old side (map or old epoch), in its frame.
        curr: planes of the current epoch, in its frame.
        pairs: (M, 2) int, (index into ``old``, index into ``curr``).
        T_old_curr: (4, 4) the current frame in the old one as the match places it.
        default_sigma_m: offset sigma of a plane without covariance, m.

    Returns:
        residuals (M,) ``d_old - d_curr`` (m) with the current plane expressed in the old
        frame and oriented like its partner; the old planes' unit normals (M, 3) in the
        old frame; the summed offset variances of both planes (M,), m^2.
    """
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    residuals, normals, variances = np.zeros(len(pairs)), np.zeros((len(pairs), 3)), []
    for row, (m, i) in enumerate(pairs):
        plane = curr[i].transformed(T_old_curr)
        sign = 1.0 if plane.normal @ old[m].normal >= 0 else -1.0
        residuals[row], normals[row] = old[m].offset - sign * plane.offset, old[m].normal
        variances.append(sum(_offset_variance(p, default_sigma_m) for p in (old[m], plane)))
    return residuals, normals, np.asarray(variances, dtype=float)


def offset_statistic(
    residuals: np.ndarray, normals: np.ndarray, variances: np.ndarray, drift_xy: np.ndarray
) -> float:
    """Largest squared whitened offset residual, chi2(1) per plane.

    Args:
        residuals: (M,) offset residuals, m (:func:`offset_residuals`).
        normals: (M, 3) the planes' unit normals in the frame of the residuals.
        variances: (M,) the planes' summed offset variances, m^2.
        drift_xy: (2, 2) covariance of the pose's horizontal position error, m^2 (in
            the frame of the normals: a position error t moves a plane's offset by n.t).

    Returns:
        max over the planes of ``r^2 / (n_xy^T drift_xy n_xy + variances)``; 0 without
        planes.
    """
    if len(residuals) == 0:
        return 0.0
    n_xy = np.asarray(normals, dtype=float)[:, :2]
    var = np.einsum("mi,ij,mj->m", n_xy, drift_xy, n_xy) + variances
    return float(np.max(np.asarray(residuals) ** 2 / var))


def _offset_variance(plane: Plane, default_sigma_m: float) -> float:
    """Offset variance (m^2) of a plane: its fit's, else the default sigma's square."""
    if plane.covariance is None:
        return default_sigma_m**2
    return float(plane.covariance[3, 3])
