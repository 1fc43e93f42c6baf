"""First-order covariance of a winning candidate from its planes' fit covariances.

A WOCSC result is one candidate, computed from one pair of planes in each epoch. Its
covariance follows from the (4, 4) covariances of ``(n, d)`` of those four planes (the
extraction's total-least-squares covariances) by linearisation; the Jacobians are taken by
central differences, in one batch. Rotation: (roll, pitch, yaw) of
``R = U(n1, n2) U(n1', n2')^T``. Translation: ``varpi_k - varpi'(z)`` of the pair, with the
uncertainty of the rotation (as a body rotation vector, covariance taken equal to the
(roll, pitch, yaw) one, valid for small angles) and of the height z added.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import block_diag
from scipy.spatial.transform import Rotation

from planodom.association import PlaneArrays
from planodom.geometry import horizontal_reference_points, rotation_frames
from planodom.odometry.rotation import rpy_of

_STEP = 1e-7


def _jacobian(f, x: np.ndarray) -> np.ndarray:
    """(m, n) central-difference Jacobian of a batched ``f: (B, n) -> (B, m)`` at ``x`` (n,)."""
    h = _STEP * np.eye(len(x))
    out = f(np.concatenate([x + h, x - h]))
    return (out[: len(x)] - out[len(x) :]).T / (2 * _STEP)


def rotation_covariance(
    prev_normals: np.ndarray,
    curr_normals: np.ndarray,
    prev_cov: np.ndarray,
    curr_cov: np.ndarray,
) -> np.ndarray:
    """(3, 3) covariance of (roll, pitch, yaw), rad^2, of the pair rotation.

    Args:
        prev_normals, curr_normals: (2, 3) the pair's normals in each epoch.
        prev_cov, curr_cov: (2, 4, 4) their planes' ``(n, d)`` covariances.
    """

    def f(x: np.ndarray) -> np.ndarray:
        U_p = rotation_frames(x[:, 0:3], x[:, 3:6])
        U_c = rotation_frames(x[:, 6:9], x[:, 9:12])
        return rpy_of(U_p @ np.swapaxes(U_c, 1, 2))

    x = np.concatenate([prev_normals.ravel(), curr_normals.ravel()])
    J = _jacobian(f, x)
    S = block_diag(*(c[:3, :3] for c in (*prev_cov, *curr_cov)))
    return J @ S @ J.T


def translation_covariance(
    prev: PlaneArrays,
    curr: PlaneArrays,
    prev_pair: np.ndarray,
    curr_pair: np.ndarray,
    prev_cov: np.ndarray,
    curr_cov: np.ndarray,
    R: np.ndarray,
    z: float,
    rotation_cov: np.ndarray,
    sigma_z: float,
    min_verticality: float,
) -> np.ndarray:
    """(2, 2) covariance, m^2, of the translation candidate of one pair.

    Args:
        prev, curr: the planes; prev_pair, curr_pair: (2,) the pair's indices.
        prev_cov, curr_cov: (2, 4, 4) the pair's plane covariances.
        R: (3, 3) the rotation; z: the height used, m.
        rotation_cov: (3, 3) covariance of the rotation (small-angle rotation vector).
        sigma_z: standard deviation of z, m (0 or inf: z taken as exact, i.e. a prior).
    """
    x = np.concatenate(
        [
            np.r_[prev.normals[prev_pair[0]], prev.offsets[prev_pair[0]]],
            np.r_[prev.normals[prev_pair[1]], prev.offsets[prev_pair[1]]],
            np.r_[curr.normals[curr_pair[0]], curr.offsets[curr_pair[0]]],
            np.r_[curr.normals[curr_pair[1]], curr.offsets[curr_pair[1]]],
            np.zeros(3),
            [z],
        ]
    )

    def f(b: np.ndarray) -> np.ndarray:
        ref_p = horizontal_reference_points(b[:, 0:3], b[:, 3], b[:, 4:7], b[:, 7], 0.0)
        Rb = R @ Rotation.from_rotvec(b[:, 16:19]).as_matrix()
        n1 = np.einsum("bij,bj->bi", Rb, b[:, 8:11])
        n2 = np.einsum("bij,bj->bi", Rb, b[:, 12:15])
        zb = b[:, 19]
        ref_c = horizontal_reference_points(
            n1, b[:, 11] - n1[:, 2] * zb, n2, b[:, 15] - n2[:, 2] * zb, 0.0
        )
        return ref_p - ref_c

    J = _jacobian(f, x)
    var_z = sigma_z**2 if np.isfinite(sigma_z) else 0.0
    S = block_diag(*prev_cov, *curr_cov, rotation_cov, [[var_z]])
    return J @ S @ J.T
