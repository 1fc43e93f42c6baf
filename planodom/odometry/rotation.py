"""3-DoF rotation from associated non-parallel plane pairs (paper II-A, eq. 1).

Each LDA pair association ``(i1, i2) -> (j1, j2)`` gives the frames ``U_k`` and
``U_{k+d}`` and the candidate ``R_prev_curr = U_k U_{k+d}^T`` (``U_{k+d} = R^-1 U_k``).
The elements of the consensus are the induced plane associations ``i -> j`` with
``x_k = n_i`` (previous normal) and ``x_{k+d} = n_j`` (current normal): a candidate is
scored by ``sum |R^-1 n_i - n_j|^2 w_i w_j`` (paper eq. 4).
"""

from __future__ import annotations

import functools

import numpy as np

from planodom.association import PairAssociations
from planodom.consensus import ConsensusResult, apply_inverse_rotation, consensus
from planodom.planes import PlaneSet


@functools.lru_cache(maxsize=256)
def chord(angle: float) -> float:
    """Distance between two unit vectors ``angle`` rad apart (remembered: the solver asks
    for the same configured angles every pass)."""
    return 2.0 * np.sin(angle / 2.0)


def rotation_consensus(
    prev: PlaneSet,
    curr: PlaneSet,
    lda: PairAssociations,
    weighted: bool = True,
    inlier_angle: float = np.radians(3.0),
) -> tuple[ConsensusResult, np.ndarray]:
    """WOCSC (``weighted``) or OCSC over the LDA rotation candidates.

    Args:
        prev, curr: the planes of the two epochs. lda: non-empty LDA result.
        inlier_angle: rad, on the angle between ``R^-1 n_i`` and ``n_j``.

    A previous plane with several current partners counts once, with its best partner
    (see :func:`planodom.consensus.consensus`, ``groups``).

    Returns:
        The consensus result (candidates are ``lda.rotations``) and the (E, 2) plane
        associations used as elements.
    """
    ij = lda.plane_associations()
    weights = prev.weights[ij[:, 0]] * curr.weights[ij[:, 1]] if weighted else None
    result = consensus(
        lda.rotations,
        prev.normals[ij[:, 0]],
        curr.normals[ij[:, 1]],
        apply_inverse_rotation,
        weights=weights,
        inlier_tol=chord(inlier_angle),
        groups=ij[:, 0],
    )
    return result, ij


def chordal_mean_rotation(rotations: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Chordal L2 mean of rotations (M, 3, 3): the weighted sum projected on SO(3) by SVD."""
    w = np.ones(len(rotations)) if weights is None else np.asarray(weights, dtype=np.float64)
    M = np.einsum("m,mij->ij", w, rotations)
    U, _, Vt = np.linalg.svd(M)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt


def rotation_angles_to(rotations: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Angles (M,), rad, between each of ``rotations`` (M, 3, 3) and ``R`` (3, 3)."""
    cos = (np.einsum("ij,mij->m", R, rotations) - 1.0) / 2.0
    return np.arccos(np.clip(cos, -1.0, 1.0))
