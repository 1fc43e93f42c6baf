"""First-order covariance of a winning candidate from its planes' fit covariances.

A WOCSC result is one candidate, computed from one pair of planes in each epoch. Its
covariance follows from the (4, 4) covariances of ``(n, d)`` of those four planes (the
extraction's total-least-squares covariances) by linearisation; the Jacobians are taken by
central differences, in one batch. Rotation (:func:`rotation_covariance`): (roll, pitch,
yaw) of ``R = U(n1, n2) U(n1', n2')^T``, or of the rotation fitted to both normals
(``odometry.pair_rotation: weighted``, :mod:`planodom.odometry.pair_rotation`, its weights
held fixed).

:func:`pose_covariance` does rotation and translation (``varpi_k - varpi'(z)`` of the
translation pair under that rotation, with the uncertainty of the height z) at once, as
functions of the distinct planes of the rotation pair and the translation pair: when the
two pairs share planes (the same pair often wins both), the rotation's error and the
translation pair's plane errors are correlated, which a translation covariance with the
rotation taken as independent misses. On the simulated loop at 6 mm the translation's NEES
was then 2.4 times too small (median 0.58 against chi2(2)'s 1.39) for relative poses whose
two pairs are one.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from planodom.geometry import (
    horizontal_reference_points,
    rotation_frame_into,
    rotation_frames,
    rpy_from_rotation,
)
from planodom.odometry.pair_rotation import weighted_pair_rotations
from planodom.planes import PlaneSet

_STEP = 1e-7


def _jacobian(f, x: np.ndarray) -> np.ndarray:
    """(m, n) central-difference Jacobian of a batched ``f: (B, n) -> (B, m)`` at ``x`` (n,)."""
    h = _STEP * np.eye(len(x))
    out = f(np.concatenate([x + h, x - h]))
    return (out[: len(x)] - out[len(x) :]).T / (2 * _STEP)


def _block_diag(blocks: list[np.ndarray]) -> np.ndarray:
    """The block-diagonal matrix of square ``blocks`` (scipy's ``block_diag`` checks and
    converts its arguments at a cost above this whole covariance's arithmetic)."""
    sizes = [len(b) for b in blocks]
    out = np.zeros((sum(sizes), sum(sizes)))
    start = 0
    for b, n in zip(blocks, sizes, strict=True):
        out[start : start + n, start : start + n] = b
        start += n
    return out


def _stacked(
    prev_normals: np.ndarray, curr_normals: np.ndarray, prev_cov: np.ndarray, curr_cov: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`rotation_covariance`'s four normals as one vector (12,) and the block-diagonal
    (12, 12) of their four normal covariances (the (3, 3) blocks of the (2, 4, 4) plane
    covariances), in one compiled copy (numpy's concatenations and slice assignments
    cost more than this covariance's arithmetic; copies: the same values)."""
    return _stacked_kernel(
        np.ascontiguousarray(prev_normals, dtype=np.float64),
        np.ascontiguousarray(curr_normals, dtype=np.float64),
        np.ascontiguousarray(prev_cov, dtype=np.float64),
        np.ascontiguousarray(curr_cov, dtype=np.float64),
    )


@numba.njit(cache=True)
def _stacked_kernel(pn, cn, pc, cc):  # pragma: no cover - compiled
    """:func:`_stacked` of C-contiguous (2, 3), (2, 3), (2, 4, 4), (2, 4, 4) arrays."""
    x = np.empty(12)
    S = np.zeros((12, 12))
    for k in range(4):
        n = pn[k] if k < 2 else cn[k - 2]
        c = pc[k] if k < 2 else cc[k - 2]
        for a in range(3):
            x[3 * k + a] = n[a]
            for b in range(3):
                S[3 * k + a, 3 * k + b] = c[a, b]
    return x, S


def _rpy(R: np.ndarray) -> np.ndarray:
    """(B, 3) roll, pitch, yaw of rotations ``R`` (B, 3, 3) = Rz(yaw) Ry(pitch) Rx(roll),
    as :func:`planodom.geometry.rpy_from_rotation` (to rounding), in closed form: scipy's
    general conversion costs more than the rest of :func:`rotation_covariance`, whose
    relative rotations are far from gimbal lock (checked: otherwise scipy's)."""
    if np.any(np.abs(R[:, 2, 0]) > 0.99):
        return rpy_from_rotation(R)
    out = np.empty((len(R), 3))
    out[:, 0] = np.arctan2(R[:, 2, 1], R[:, 2, 2])
    out[:, 1] = np.arctan2(-R[:, 2, 0], np.hypot(R[:, 0, 0], R[:, 1, 0]))
    out[:, 2] = np.arctan2(R[:, 1, 0], R[:, 0, 0])
    return out


def rotation_covariance(
    prev_normals: np.ndarray,
    curr_normals: np.ndarray,
    prev_cov: np.ndarray,
    curr_cov: np.ndarray,
    weights: np.ndarray | None = None,
) -> np.ndarray:
    """(3, 3) covariance of (roll, pitch, yaw), rad^2, of the pair rotation.

    Args:
        prev_normals, curr_normals: (2, 3) the pair's normals in each epoch.
        prev_cov, curr_cov: (2, 4, 4) their planes' ``(n, d)`` covariances.
        weights: (2,) the weights of the pair's rotation fitted to both normals
            (:mod:`planodom.odometry.pair_rotation`, held fixed); None: the paper's frames.
    """

    x, S = _stacked(prev_normals, curr_normals, prev_cov, curr_cov)
    if weights is not None:
        J = _jacobian(lambda b: _rpy(_weighted(b[:, :6], b[:, 6:], weights)), x)
        return J @ S @ J.T
    J = _rotation_jacobian(x, _STEP)
    if math.isnan(J[0, 0]):  # near gimbal lock: scipy's conversion (see _rpy)

        def f(x: np.ndarray) -> np.ndarray:
            U_p = rotation_frames(x[:, 0:3], x[:, 3:6])
            U_c = rotation_frames(x[:, 6:9], x[:, 9:12])
            return _rpy(U_p @ np.swapaxes(U_c, 1, 2))

        J = _jacobian(f, x)
    return J @ S @ J.T


def _weighted(prev: np.ndarray, curr: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(B, 3, 3) the rotations fitted to both normals (:func:`.pair_rotation.
    weighted_pair_rotations`) of ``B`` pairs given as (B, 6) rows ``n1, n2`` of each epoch,
    the normals made unit (as the paper's frames make them), ``weights`` (2,) fixed."""
    p, c = prev.reshape(-1, 2, 3), curr.reshape(-1, 2, 3)
    p = p / np.linalg.norm(p, axis=2, keepdims=True)
    c = c / np.linalg.norm(c, axis=2, keepdims=True)
    return weighted_pair_rotations(p, c, np.broadcast_to(weights, (len(p), 2)))


@numba.njit(cache=True)
def _rotation_jacobian(x, step):  # pragma: no cover - compiled
    """(3, 12) central-difference Jacobian of the pair rotation's (roll, pitch, yaw) with
    respect to the four normals ``x`` (12,) (:func:`rotation_covariance`), compiled: the
    batched numpy version's ~30 small calls cost ten times its arithmetic. NaN at [0, 0]
    when an evaluation is near gimbal lock (``|R[2, 0]| > 0.99``, see :func:`_rpy`)."""
    J = np.empty((3, 12))
    U_p = np.empty((3, 3))
    U_c = np.empty((3, 3))
    rpy = np.empty((2, 3))
    for k in range(12):
        for side in range(2):
            y = x.copy()
            y[k] += step if side == 0 else -step
            rotation_frame_into(y[0:3], y[3:6], U_p)
            rotation_frame_into(y[6:9], y[9:12], U_c)
            R = U_p @ U_c.T
            if abs(R[2, 0]) > 0.99:
                J[0, 0] = np.nan
                return J
            rpy[side, 0] = np.arctan2(R[2, 1], R[2, 2])
            rpy[side, 1] = np.arctan2(-R[2, 0], np.hypot(R[0, 0], R[1, 0]))
            rpy[side, 2] = np.arctan2(R[1, 0], R[0, 0])
        for a in range(3):
            J[a, k] = (rpy[0, a] - rpy[1, a]) / (2 * step)
    return J


def pose_covariance(
    prev: PlaneSet,
    curr: PlaneSet,
    rotation_pair: np.ndarray,
    translation_pair: np.ndarray,
    z: float,
    sigma_z: float,
    rotation_weights: np.ndarray | None = None,
) -> np.ndarray:
    """(5, 5) covariance of (roll, pitch, yaw, x, y), rad and m, of a relative pose.

    The rotation comes from ``rotation_pair``, the translation from ``translation_pair``
    under that rotation at height ``z``, both as functions of the distinct planes of the
    two pairs (module docstring), so shared planes are counted once and the
    rotation-translation correlation is kept.

    Args:
        prev, curr: the planes (``covariances`` must be finite for the pairs' planes).
        rotation_pair, translation_pair: (4,) ``(i1, i2, j1, j2)``: planes i1, i2 of
            ``prev`` associated with j1, j2 of ``curr``.
        z: the height used, m. sigma_z: its standard deviation, m (0 or inf: exact).
        rotation_weights: (2,) as :func:`rotation_covariance`'s ``weights``.
    """
    rp, tp = np.asarray(rotation_pair, dtype=int), np.asarray(translation_pair, dtype=int)
    ids_p = list(dict.fromkeys([*rp[:2], *tp[:2]]))
    ids_c = list(dict.fromkeys([*rp[2:], *tp[2:]]))
    n_p = len(ids_p)

    def cols(indices: list[int], offset: int) -> list[slice]:
        return [slice(offset + 4 * k, offset + 4 * k + 4) for k in range(len(indices))]

    at_p, at_c = cols(ids_p, 0), cols(ids_c, 4 * n_p)
    col = {("p", i): at_p[k] for k, i in enumerate(ids_p)}
    col |= {("c", j): at_c[k] for k, j in enumerate(ids_c)}
    x = np.concatenate(
        [np.r_[prev.normals[i], prev.offsets[i]] for i in ids_p]
        + [np.r_[curr.normals[j], curr.offsets[j]] for j in ids_c]
        + [[z]]
    )

    def plane(b: np.ndarray, side: str, index: int) -> tuple[np.ndarray, np.ndarray]:
        s = col[(side, int(index))]
        return b[:, s.start : s.start + 3], b[:, s.start + 3]

    def f(b: np.ndarray) -> np.ndarray:
        (p1, _), (p2, _) = plane(b, "p", rp[0]), plane(b, "p", rp[1])
        (c1, _), (c2, _) = plane(b, "c", rp[2]), plane(b, "c", rp[3])
        if rotation_weights is None:
            R = rotation_frames(p1, p2) @ np.swapaxes(rotation_frames(c1, c2), 1, 2)
        else:
            R = _weighted(np.hstack([p1, p2]), np.hstack([c1, c2]), rotation_weights)
        (m1, e1), (m2, e2) = plane(b, "p", tp[0]), plane(b, "p", tp[1])
        (k1, f1), (k2, f2) = plane(b, "c", tp[2]), plane(b, "c", tp[3])
        ref_p = horizontal_reference_points(m1, e1, m2, e2, 0.0)
        n1 = np.einsum("bij,bj->bi", R, k1)
        n2 = np.einsum("bij,bj->bi", R, k2)
        zb = b[:, -1]
        ref_c = horizontal_reference_points(n1, f1 - n1[:, 2] * zb, n2, f2 - n2[:, 2] * zb, 0.0)
        return np.column_stack([rpy_from_rotation(R), ref_p - ref_c])

    J = _jacobian(f, x)
    var_z = sigma_z**2 if np.isfinite(sigma_z) else 0.0
    S = _block_diag(
        [*(prev.covariances[i] for i in ids_p), *(curr.covariances[j] for j in ids_c),
         np.array([[var_z]])]
    )  # fmt: skip
    return J @ S @ J.T
