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
import numba
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


#: Below this squared angle gtsam 4.3 takes the inverse right Jacobian's coefficient from its
#: Taylor series (``so3::DexpFunctor``'s near-zero threshold).
_NEAR_ZERO_THETA2 = 1e-6


@numba.njit(cache=True)
def _logmap(R: np.ndarray) -> tuple[np.ndarray, bool]:
    """(3,) rotation vector of a (3, 3) rotation matrix, rad, as gtsam's ``SO3::Logmap``
    computes it for angles below 90 degrees (``theta / (2 sin theta)`` from the trace, its
    Taylor series near 0); and whether the angle is below 90 degrees (trace > 1). Above,
    gtsam's branches near pi differ: the caller asks gtsam."""
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    omega = np.empty(3)
    if not tr > 1.0:
        return omega, False
    tr_3 = tr - 3.0
    if tr_3 < -1e-6:
        theta = np.arccos((tr - 1.0) / 2.0)
        magnitude = theta / (2.0 * np.sin(theta))
    else:
        magnitude = 0.5 - tr_3 / 12.0 + tr_3 * tr_3 / 60.0
    omega[0] = magnitude * (R[2, 1] - R[1, 2])
    omega[1] = magnitude * (R[0, 2] - R[2, 0])
    omega[2] = magnitude * (R[1, 0] - R[0, 1])
    return omega, True


@numba.njit(cache=True)
def _logmap_derivative(w: np.ndarray) -> np.ndarray:
    """(3, 3) inverse right Jacobian of SO(3) at the rotation vector ``w`` (3,), as gtsam
    4.3's ``SO3::LogmapDerivative``: ``I + W / 2 + D W^2`` with ``W = [w]_x``,
    ``D = (1 - A / (2 B)) / theta^2``, ``A = sin(theta) / theta``,
    ``B = 2 sin^2(theta / 2) / theta^2``; ``D = 1/12 + theta^2 / 720`` near 0."""
    theta2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    if theta2 <= _NEAR_ZERO_THETA2:
        D = 1.0 / 12.0 + theta2 / 720.0
    else:
        theta = np.sqrt(theta2)
        A = np.sin(theta) / theta
        s2 = np.sin(theta / 2.0)
        B = 2.0 * s2 * s2 / theta2
        D = (1.0 - A / (2.0 * B)) / theta2
    W = _skew(w)
    out = np.eye(3)
    for r in range(3):
        for q in range(3):
            WW = W[r, 0] * W[0, q] + W[r, 1] * W[1, q] + W[r, 2] * W[2, q]
            out[r, q] = out[r, q] + 0.5 * W[r, q] + D * WW
    return out


@numba.njit(cache=True)
def _skew(v: np.ndarray) -> np.ndarray:
    out = np.zeros((3, 3))
    out[0, 1], out[0, 2], out[1, 2] = -v[2], v[1], -v[0]
    out[1, 0], out[2, 0], out[2, 1] = v[2], -v[1], v[0]
    return out


@numba.njit(cache=True)
def _pose5_kernel(
    T_i_j: np.ndarray, T_world_i: np.ndarray, T_world_j: np.ndarray, jacobians: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """:func:`pose5_error` compiled (it runs once per factor and linearisation): error
    (5,), H_i and H_j (5, 6) (zeros when ``jacobians`` is false), and false where the
    rotation error exceeds 90 degrees (then nothing is computed: see :func:`_logmap`)."""
    R_pred = np.empty((3, 3))
    R_err = np.empty((3, 3))
    d = np.empty(3)
    t_pred = np.empty(3)
    error = np.empty(5)
    H_i = np.zeros((5, 6))
    H_j = np.zeros((5, 6))
    for r in range(3):
        d[r] = T_world_j[r, 3] - T_world_i[r, 3]
    for r in range(3):  # R_pred = R_i^T R_j, t_pred = R_i^T (t_j - t_i)
        for q in range(3):
            R_pred[r, q] = (
                T_world_i[0, r] * T_world_j[0, q]
                + T_world_i[1, r] * T_world_j[1, q]
                + T_world_i[2, r] * T_world_j[2, q]
            )
        t_pred[r] = T_world_i[0, r] * d[0] + T_world_i[1, r] * d[1] + T_world_i[2, r] * d[2]
    for r in range(3):  # R_meas^T R_pred
        for q in range(3):
            R_err[r, q] = (
                T_i_j[0, r] * R_pred[0, q] + T_i_j[1, r] * R_pred[1, q] + T_i_j[2, r] * R_pred[2, q]
            )
    e_rot, ok = _logmap(R_err)
    if not ok:
        return error, H_i, H_j, False
    error[:3] = e_rot
    error[3] = t_pred[0] - T_i_j[0, 3]
    error[4] = t_pred[1] - T_i_j[1, 3]
    if not jacobians:
        return error, H_i, H_j, True
    Jr_inv = _logmap_derivative(e_rot)
    for r in range(3):
        for q in range(3):
            H_i[r, q] = -(
                Jr_inv[r, 0] * R_pred[q, 0]
                + Jr_inv[r, 1] * R_pred[q, 1]
                + Jr_inv[r, 2] * R_pred[q, 2]
            )
            H_j[r, q] = Jr_inv[r, q]
    S = _skew(t_pred)
    for r in range(2):
        for q in range(3):
            H_i[3 + r, q] = S[r, q]
            H_j[3 + r, 3 + q] = R_pred[r, q]
    H_i[3, 3] = H_i[4, 4] = -1.0
    return error, H_i, H_j, True


def _pose5_error_gtsam(
    T_i_j: np.ndarray, T_world_i: np.ndarray, T_world_j: np.ndarray, jacobians: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`pose5_error` by numpy and gtsam's own ``Rot3.Logmap`` (rotation errors above
    90 degrees, where :func:`_logmap` defers to gtsam)."""
    Ri_T = T_world_i[:3, :3].T
    R_pred = Ri_T @ T_world_j[:3, :3]
    t_pred = Ri_T @ (T_world_j[:3, 3] - T_world_i[:3, 3])
    e_rot = gtsam.Rot3.Logmap(gtsam.Rot3(T_i_j[:3, :3].T @ R_pred))
    error = np.empty(5)
    error[:3] = e_rot
    error[3:] = t_pred[:2] - T_i_j[:2, 3]
    H_i = np.zeros((5, 6))
    H_j = np.zeros((5, 6))
    if jacobians:
        Jr_inv = gtsam.Rot3.LogmapDerivative(e_rot)
        H_i[:3, :3] = -Jr_inv @ R_pred.T
        H_j[:3, :3] = Jr_inv
        H_i[3:, :3] = _skew(t_pred)[:2]
        H_i[3, 3] = H_i[4, 4] = -1.0
        H_j[3:, 3:] = R_pred[:2]
    return error, H_i, H_j


def _pose5(
    T_i_j: np.ndarray, T_world_i: np.ndarray, T_world_j: np.ndarray, jacobians: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Error (5,) and Jacobians (5, 6) of three (4, 4) float arrays: compiled, or by gtsam
    for a rotation error above 90 degrees."""
    error, H_i, H_j, ok = _pose5_kernel(T_i_j, T_world_i, T_world_j, jacobians)
    if ok:
        return error, H_i, H_j
    return _pose5_error_gtsam(T_i_j, T_world_i, T_world_j, jacobians)


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
    error, H_i, H_j = _pose5(
        _matrix(T_i_j), _matrix(T_world_i), _matrix(T_world_j), bool(jacobians)
    )
    if not jacobians:
        return error, None, None
    return error, H_i, H_j


class _Precomputed:
    """Residuals and Jacobians of many of the factors below computed in one compiled pass
    (:mod:`planodom_factors.batched`), which their callbacks hand to gtsam instead of
    computing their own, while ``values`` is the ``gtsam.Values`` being evaluated (the
    same numbers either way: the same kernels on the same poses).

    Each factor's callback holds a cell (a one-item list) bound at construction, which
    the batch writes its row into (:class:`.batched.BatchedResiduals`, before it
    evaluates): a list item read, where looking the row up by the factor's identity
    (a tuple built, hashed and found in a dict, in a helper call) cost about 1.2 us of a
    callback's 2.1 (BATCH15; 1.25 M callbacks in the 2 000-epoch batch). (Not the factor
    object: gtsam hands each callback a new copy; the bound arguments are the same.)

    Attributes:
        values: the values they were computed at, or None (no batch being evaluated).
        owner: the batch whose rows the cells hold (it writes them when it is not).
        errors: (F, 5) residuals (a vertical factor's in column 0).
        H_i, H_j: (F, 5, 6) Jacobians, or None when only the errors were computed.
        ok: (F,) false where the compiled kernel deferred to gtsam (see :func:`_pose5`).
        record: while a list, each callback appends ``(measured (4, 4) or None, dz,
            key_i, key_j, cell)`` when not precomputed (:func:`.batched.record`).
    """

    values: gtsam.Values | None = None
    owner: object = None
    errors: np.ndarray = np.zeros((0, 5))
    H_i: np.ndarray | None = None
    H_j: np.ndarray | None = None
    ok: np.ndarray = np.zeros(0, dtype=bool)
    record: list[tuple] | None = None


def _pose5_error(
    measured: np.ndarray,
    rows: slice,
    key_i: int,
    key_j: int,
    cell: list[int],
    this: gtsam.CustomFactor,
    values: gtsam.Values,
    H: Jacobians,
) -> np.ndarray:
    """``gtsam.CustomFactor`` error of :func:`pose5_error`'s ``rows`` (keys bound at
    construction: the factor's own ``keys()`` costs a call into gtsam per evaluation;
    ``cell``: its row in the batch, :class:`_Precomputed`)."""
    p = _Precomputed
    r = cell[0]
    if r >= 0 and p.values is values and p.ok[r] and (H is None or p.H_i is not None):
        if H is not None:
            H[0], H[1] = p.H_i[r, rows], p.H_j[r, rows]  # type: ignore[index]
        return p.errors[r, rows]
    if p.record is not None:
        p.record.append((measured, 0.0, key_i, key_j, cell))
    error, H_i, H_j = _pose5(
        measured, values.atPose3(key_i).matrix(), values.atPose3(key_j).matrix(), H is not None
    )
    if H is not None:
        H[0], H[1] = H_i[rows], H_j[rows]
    return error[rows]


@numba.njit(cache=True)
def _vertical_kernel(
    dz: float, T_i: np.ndarray, T_j: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Error (1,) of the change of height against ``dz`` (m) and its (1, 6) Jacobians."""
    # t' = t + R v: the height moves by the third row of R.
    H_i = np.zeros((1, 6))
    H_j = np.zeros((1, 6))
    for q in range(3):
        H_i[0, 3 + q] = -T_i[2, q]
        H_j[0, 3 + q] = T_j[2, q]
    error = np.empty(1)
    error[0] = T_j[2, 3] - T_i[2, 3] - dz
    return error, H_i, H_j


def _vertical_error(
    dz: float,
    key_i: int,
    key_j: int,
    cell: list[int],
    this: gtsam.CustomFactor,
    values: gtsam.Values,
    H: Jacobians,
) -> np.ndarray:
    """``gtsam.CustomFactor`` error of the change of height against ``dz`` (m)."""
    # _pose5_error's fast path, inline: a shared helper would add a Python call to each of
    # the batch's evaluations (about 1.25 M on the 2 000-epoch lap, BATCH15)
    p = _Precomputed
    r = cell[0]
    if r >= 0 and p.values is values and p.ok[r] and (H is None or p.H_i is not None):
        if H is not None:
            H[0], H[1] = p.H_i[r, :1], p.H_j[r, :1]  # type: ignore[index]
        return p.errors[r, :1]
    if p.record is not None:
        p.record.append((None, dz, key_i, key_j, cell))
    error, H_i, H_j = _vertical_kernel(
        dz, values.atPose3(key_i).matrix(), values.atPose3(key_j).matrix()
    )
    if H is not None:
        H[0], H[1] = H_i, H_j
    return error


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
        noise,
        [key_i, key_j],
        partial(_pose5_error, _matrix(T_i_j), slice(0, 5), key_i, key_j, [-1]),
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
        noise,
        [key_i, key_j],
        partial(_pose5_error, _matrix(T_i_j), slice(0, 3), key_i, key_j, [-1]),
    )


def vertical_factor(
    key_i: int, key_j: int, dz: float = 0.0, noise: Noise = VERTICAL_NOISE
) -> gtsam.CustomFactor:
    """1-DoF factor on the change of height ``z_j - z_i`` (world frame) against ``dz``, m.

    With ``dz = 0`` and a weak sigma it is the "no vertical jumps" prior that makes z
    observable when the plane factors do not observe it.
    """
    return gtsam.CustomFactor(
        noise, [key_i, key_j], partial(_vertical_error, float(dz), key_i, key_j, [-1])
    )
