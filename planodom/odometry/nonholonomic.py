"""The non-holonomic constraint of a degenerate step (``odometry.nonholonomic_sigma_m``).

A wheeled vehicle whose base frame is its own (x forward, origin on the rear axle: the
point without lateral velocity) moves over a step of constant body twist ``(w, v)`` with
``v_y = 0``. Its step ``T_prev_curr = exp((w, v) dt)`` then has a logarithm without a
lateral component: ``(J_l(phi)^-1 t)_y = 0`` with ``phi`` the step's rotation vector and
``t`` its translation (:func:`planodom.geometry.se3_log`), one linear equation in ``t``
once the rotation is known. In a turn it ties the step's along-track and lateral
components (``t_y = t_x tan(yaw / 2)`` for a level arc), so a degenerate step whose
planes measure one oblique horizontal direction (the ground and a wall at an angle to
the track) gets the other from it instead of from the prediction, whose along-track
velocity at a start-up came from an unmeasured step itself (issue 11: generalisation
world 2 at 2 cm, first step degenerate, 49 cm off).
"""

from __future__ import annotations

import numpy as np

from planodom.config import OdometryConfig
from planodom.geometry import make_transform, se3_log


def lateral_row(R: np.ndarray) -> np.ndarray:
    """(3,) unit ``c`` with ``c . t = 0`` for the translation ``t`` (3,) of a step of
    rotation ``R`` (3, 3) made with no lateral body velocity: the second row of the
    inverse left Jacobian ``I - [phi]x / 2 + k [phi]x^2`` of ``phi = log(R)`` (as
    :func:`planodom.geometry.se3_log`), normalised."""
    phi = se3_log(make_transform(np.asarray(R, dtype=np.float64), np.zeros(3)))[:3]
    a = float(np.linalg.norm(phi))
    k = 1.0 / 12.0 if a < 1e-6 else 1.0 / a**2 - (1.0 + np.cos(a)) / (2.0 * a * np.sin(a))
    K = np.array([[0.0, -phi[2], phi[1]], [phi[2], 0.0, -phi[0]], [-phi[1], phi[0], 0.0]])
    row = (np.eye(3) - 0.5 * K + k * (K @ K))[1]
    return row / np.linalg.norm(row)


#: The kernel's plane arrays: previous normals, offsets, covariances, current ones, R.
KernelPlanes = tuple[
    np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray
]


def with_lateral(args: KernelPlanes, R: np.ndarray, sigma_m: float) -> KernelPlanes:
    """The plane associations ``args`` of :func:`planodom.odometry.refine.plane_translation`'s
    kernel (previous normals (L, 3), offsets (L,), covariances (L, 4, 4), the current ones,
    ``R`` (3, 3)) with the constraint appended as one more association: normals ``c`` and
    ``R^T c`` (so that its ``m`` is ``c``), offsets 0 (``c . t = 0``), the offsets'
    variance ``sigma_m^2`` (split between the two) and none on the normals."""
    n_i, d_i, c_i, n_j, d_j, c_j, R_ = args
    c = lateral_row(R)
    cov = np.zeros((1, 4, 4))
    cov[0, 3, 3] = sigma_m**2 / 2.0
    return (
        np.vstack((n_i, c)), np.append(d_i, 0.0), np.concatenate((c_i, cov)),
        np.vstack((n_j, R.T @ c)), np.append(d_j, 0.0), np.concatenate((c_j, cov)), R_,
    )  # fmt: skip


def lateral_sigma(config: OdometryConfig) -> float:
    """The constraint's sigma, m, a degenerate step's translation is solved with under
    ``config`` (``odometry.nonholonomic_sigma_m`` with a non-holonomic
    ``odometry.motion_model``; 0: not used)."""
    if config.motion_model == "constant_velocity":
        return 0.0
    return float(config.nonholonomic_sigma_m)
