"""An LDA pair's candidate rotation fitted to both its normals (``odometry.pair_rotation``).

The paper's candidate of a pair association ``(i1, i2) -> (j1, j2)`` (eq. 1,
:func:`planodom.geometry.rotation_frames`) is ``U_k U_{k+d}^T`` with ``U = [n1, n2', n1 x
n2]``: it maps ``n_j1`` onto ``n_i1`` exactly and takes only the rotation about that
normal from the second pair. Whatever error the first normal has goes whole into the
rotation: a ground-and-wall pair whose wall comes first takes the wall's tilt error (a 2D
rig sees a wall on two scan lines) into roll and pitch (docs/RESULTS.md, RANGE166: world
166's steps 37-39 at 2 cm, 1.2-2.4 deg, and 0.4-0.8 deg weighted).

``weighted``: the rotation minimising ``sum_k w_k |n_ik - R n_jk|^2`` over the pair's two
normal associations (Wahba's problem), ``w_k`` the inverse of the association's normal
variance (:func:`planodom.odometry.refine.normal_variances`, plus the refinement's floor
``refine_normal_floor_deg`` squared, as ``refinement: pose`` weighs). Closed form: with
``B = sum_k w_k n_ik n_jk^T = U S V^T``, ``R = U diag(1, 1, det(U V^T)) V^T``. Written here
over all pairs at once (one batched SVD) rather than by scipy's
``Rotation.align_vectors``, which solves one set of vectors per call: an epoch pair has up
to hundreds of candidates, and the closed form is the same (the tests compare the two).
The association's gates (LDA's rotation bound, reference points) stay the paper's; the
result is deterministic.

``winner``: the consensus scores the paper's candidates (the same winner as the paper's)
and only the winner's rotation is fitted to both its normals (:func:`winner_rotation`).
Weighted candidates lower every pair's own misfit, a pair of two walls of equal weight
the most (half its dihedral misfit on each), so walls-only pairs win more steps and bring
the walls' poorly measured tilt into roll and pitch (docs/RESULTS.md, WPROC).
"""

from __future__ import annotations

import numpy as np

from planodom.angles import radians
from planodom.association import PairAssociations
from planodom.config import OdometryConfig
from planodom.odometry.refine import normal_variances
from planodom.planes import PlaneSet


def weighted_pair_rotations(
    prev_normals: np.ndarray, curr_normals: np.ndarray, weights: np.ndarray
) -> np.ndarray:
    """(M, 3, 3) rotations ``R_prev_curr`` minimising ``sum_k w_k |p_k - R c_k|^2``.

    Args:
        prev_normals, curr_normals: (M, 2, 3) each pair's two unit normals ``p_k``, ``c_k``
            (non-parallel).
        weights: (M, 2) positive weights ``w_k`` (only their ratio matters).
    """
    w = weights / weights.sum(axis=1, keepdims=True)
    B = np.einsum("mk,mki,mkj->mij", w, prev_normals, curr_normals)
    U, _, Vt = np.linalg.svd(B)
    D = np.ones((len(B), 3))
    D[:, 2] = np.sign(np.linalg.det(U) * np.linalg.det(Vt))
    return np.einsum("mij,mj,mjk->mik", U, D, Vt)


def pair_weights(
    prev: PlaneSet, curr: PlaneSet, prev_pairs: np.ndarray, curr_pairs: np.ndarray, floor: float
) -> np.ndarray:
    """(M, 2) weights of the pairs' normal associations ``prev_pairs[:, k] ->
    curr_pairs[:, k]`` (M, 2): inverse normal variances plus ``floor`` rad squared."""
    var = normal_variances(prev.covariances[prev_pairs], curr.covariances[curr_pairs])
    return 1.0 / (var + floor**2)


def candidate_pairs(
    prev: PlaneSet, curr: PlaneSet, lda: PairAssociations, ocfg: OdometryConfig
) -> PairAssociations:
    """``lda`` with its candidate rotations fitted to both normals when
    ``ocfg.pair_rotation`` is ``"weighted"`` (module docstring); ``lda`` itself otherwise
    (the paper's)."""
    if ocfg.pair_rotation != "weighted" or len(lda) == 0:
        return lda
    pp, cp = lda.prev_pairs, lda.curr_pairs
    w = pair_weights(prev, curr, pp, cp, radians(ocfg.refine_normal_floor_deg))
    R = weighted_pair_rotations(prev.normals[pp], curr.normals[cp], w)
    return PairAssociations(pp, cp, R, lda.weights)


def rotation_weights(
    prev: PlaneSet,
    curr: PlaneSet,
    prev_pair: np.ndarray,
    curr_pair: np.ndarray,
    ocfg: OdometryConfig,
) -> np.ndarray | None:
    """(2,) the weights of one pair's two normal associations ``prev_pair -> curr_pair``
    (2,) under ``odometry.pair_rotation`` ``weighted`` or ``winner`` (what its covariance
    is propagated through, :mod:`planodom.odometry.propagate`); None for the paper's
    candidate."""
    if ocfg.pair_rotation == "first":
        return None
    floor = radians(ocfg.refine_normal_floor_deg)
    return pair_weights(prev, curr, prev_pair[None], curr_pair[None], floor)[0]


def winner_rotation(
    prev: PlaneSet,
    curr: PlaneSet,
    prev_pair: np.ndarray,
    curr_pair: np.ndarray,
    R: np.ndarray,
    ocfg: OdometryConfig,
) -> np.ndarray:
    """The consensus winner's rotation (3, 3): its pair ``prev_pair -> curr_pair`` (2,)
    fitted to both normals under ``odometry.pair_rotation: winner``, else ``R`` (its
    candidate) as it is (module docstring)."""
    if ocfg.pair_rotation != "winner":
        return R
    w = rotation_weights(prev, curr, prev_pair, curr_pair, ocfg)
    assert w is not None
    n_p, n_c = prev.normals[prev_pair][None], curr.normals[curr_pair][None]
    return weighted_pair_rotations(n_p, n_c, w[None])[0]
