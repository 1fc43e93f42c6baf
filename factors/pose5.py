"""A 5-DoF between factor on two ``gtsam.Pose3``: roll, pitch, yaw and horizontal x, y.

The paper's odometry resolves the relative rotation (3 DoF) and the horizontal translation
(2 DoF) between epochs; the vertical translation is unobserved. The factor constrains
exactly those 5 components of the predicted relative pose ``T_i^-1 T_j`` and leaves z
free (it is not a ``BetweenFactorPose3`` with a made-up huge z sigma):

    e = [ Log(R_meas^T R_pred)                      (3, rad: rotation error vector)
          (t_pred - t_meas)[x, y] in frame i        (2, m) ]

with ``R_pred = R_i^T R_j`` and ``t_pred = R_i^T (t_j - t_i)``. The noise model's sigmas are
ordered (rot x, rot y, rot z, x, y); for small roll and pitch, the rotation error vector's
components are the roll, pitch and yaw errors.

A companion 1-DoF factor constrains the change of height ``(t_j - t_i)[z]`` in the world
frame: with a weak sigma it is the "the vehicle does not jump vertically" prior that keeps
z observable when only vertical walls are seen (see :mod:`planodom.smoothing.graph` on
observability). It is world-vertical on purpose: in the pitched base frame a level motion
has a vertical component.

Jacobians are analytic, with respect to gtsam's Pose3 tangent ``[omega (3), v (3)]`` and its
right perturbation ``T' = T Exp(xi)`` (so ``R' = R Exp(omega)``, ``t' = t + R v`` to first
order). Writing ``Jr^-1`` for the inverse right Jacobian of SO(3) at ``e_rot``:

    d e_rot / d omega_i = -Jr^-1 R_pred^T     d e_rot / d omega_j = Jr^-1
    d t_pred / d omega_i = [t_pred]_x         d t_pred / d v_i = -I
    d t_pred / d v_j = R_pred                 (all other blocks are zero)
"""

from __future__ import annotations

from functools import partial

import gtsam
import numpy as np

Transform = np.ndarray | gtsam.Pose3
Noise = gtsam.noiseModel.Base
Jacobians = list[np.ndarray] | None

#: Default noise of a 5-DoF relative pose: (rot x, rot y, rot z) rad, (x, y) m.
POSE5_NOISE = gtsam.noiseModel.Diagonal.Sigmas(np.array([1e-3, 1e-3, 1e-3, 1e-2, 1e-2]))

#: Default noise of a relative rotation alone, rad.
ROTATION_NOISE = gtsam.noiseModel.Isotropic.Sigma(3, 1e-3)

#: Default weak prior on the change of height between epochs, m.
VERTICAL_NOISE = gtsam.noiseModel.Isotropic.Sigma(1, 0.05)


def _matrix(T: Transform) -> np.ndarray:
    """(4, 4) float64 copy of a transform or Pose3."""
    return np.array(T.matrix() if isinstance(T, gtsam.Pose3) else T, dtype=float).reshape(4, 4)


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def pose5_error(
    T_i_j: np.ndarray,
    T_world_i: np.ndarray,
    T_world_j: np.ndarray,
    jacobians: bool = False,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """5-DoF error (5,) of ``T_world_i^-1 T_world_j`` against ``T_i_j`` (module docstring).

    Args:
        T_i_j: (4, 4) the measured relative pose (its z is ignored).
        T_world_i, T_world_j: (4, 4) the two poses.
        jacobians: also return the (5, 6) Jacobians w.r.t. both poses (gtsam tangent).

    Returns:
        error (5,): rad (3), m (2); and H_i, H_j (or None when not asked for).
    """
    Ri_T = T_world_i[:3, :3].T
    R_pred = Ri_T @ T_world_j[:3, :3]
    t_pred = Ri_T @ (T_world_j[:3, 3] - T_world_i[:3, 3])
    e_rot = gtsam.Rot3.Logmap(gtsam.Rot3(T_i_j[:3, :3].T @ R_pred))
    error = np.empty(5)
    error[:3] = e_rot
    error[3:] = t_pred[:2] - T_i_j[:2, 3]
    if not jacobians:
        return error, None, None
    Jr_inv = gtsam.Rot3.LogmapDerivative(e_rot)
    H_i = np.zeros((5, 6))
    H_j = np.zeros((5, 6))
    H_i[:3, :3] = -Jr_inv @ R_pred.T
    H_j[:3, :3] = Jr_inv
    H_i[3:, :3] = _skew(t_pred)[:2]
    H_i[3, 3] = H_i[4, 4] = -1.0
    H_j[3:, 3:] = R_pred[:2]
    return error, H_i, H_j


def _poses(this: gtsam.CustomFactor, values: gtsam.Values) -> tuple[np.ndarray, np.ndarray]:
    """The (4, 4) matrices of a two-pose custom factor's variables ``T_world_i, T_world_j``."""
    keys = this.keys()
    return values.atPose3(keys[0]).matrix(), values.atPose3(keys[1]).matrix()


def _pose5_error(
    measured: np.ndarray, rows: slice, this: gtsam.CustomFactor, values: gtsam.Values, H: Jacobians
) -> np.ndarray:
    """``gtsam.CustomFactor`` error of :func:`pose5_error`'s ``rows``."""
    error, H_i, H_j = pose5_error(measured, *_poses(this, values), H is not None)
    if H is not None:
        assert H_i is not None and H_j is not None
        H[0], H[1] = H_i[rows], H_j[rows]
    return error[rows]


def _vertical_error(
    dz: float, this: gtsam.CustomFactor, values: gtsam.Values, H: Jacobians
) -> np.ndarray:
    """``gtsam.CustomFactor`` error of the change of height against ``dz`` (m)."""
    T_i, T_j = _poses(this, values)
    if H is not None:
        # t' = t + R v: the height moves by the third row of R.
        H_i = np.zeros((1, 6))
        H_j = np.zeros((1, 6))
        H_i[0, 3:] = -T_i[2, :3]
        H_j[0, 3:] = T_j[2, :3]
        H[0], H[1] = H_i, H_j
    return np.array([T_j[2, 3] - T_i[2, 3] - dz])


def pose5_factor(
    key_i: int, key_j: int, T_i_j: Transform, noise: Noise = POSE5_NOISE
) -> gtsam.CustomFactor:
    """5-DoF between factor (roll, pitch, yaw, x, y of ``T_i_j``; z free).

    Args:
        key_i, key_j: keys of ``T_world_i`` and ``T_world_j`` (Pose3).
        T_i_j: (4, 4) measured relative transform (its z is ignored) or a Pose3.
        noise: 5-dimensional noise model, sigmas (rot x, rot y, rot z) rad, (x, y) m;
            may be robust.
    """
    return gtsam.CustomFactor(
        noise, [key_i, key_j], partial(_pose5_error, _matrix(T_i_j), slice(0, 5))
    )


def rotation_factor(
    key_i: int, key_j: int, T_i_j: Transform, noise: Noise = ROTATION_NOISE
) -> gtsam.CustomFactor:
    """The rotation rows of :func:`pose5_factor` alone (relative rotation measured,
    horizontal translation not: the odometry's "degenerate" epochs).

    Args:
        key_i, key_j: keys of ``T_world_i`` and ``T_world_j``.
        T_i_j: (4, 4) measured relative transform (only its rotation is used) or a Pose3.
        noise: 3-dimensional noise model (rad); may be robust.
    """
    return gtsam.CustomFactor(
        noise, [key_i, key_j], partial(_pose5_error, _matrix(T_i_j), slice(0, 3))
    )


def vertical_factor(
    key_i: int, key_j: int, dz: float = 0.0, noise: Noise = VERTICAL_NOISE
) -> gtsam.CustomFactor:
    """1-DoF factor on the change of height ``z_j - z_i`` (world frame) against ``dz``, m.

    With ``dz = 0`` and a weak sigma it is the "no vertical jumps" prior that makes z
    observable when the plane factors do not observe it.
    """
    return gtsam.CustomFactor(noise, [key_i, key_j], partial(_vertical_error, float(dz)))
