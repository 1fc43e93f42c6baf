"""Pose marginals of a linearised smoothing graph by the Schur complement on the landmarks.

Every landmark's variables (an anchored landmark's anchor ``A(j)`` and plane ``L(j)``, or a
global landmark's ``L(j)``) share factors only with each other and with poses: the
information matrix, ordered poses first, is

    H = [[H_pp, H_pl], [H_lp, H_ll]],  H_ll block diagonal (one block per landmark),

so the poses' marginal information is ``S = H_pp - sum_j H_pj H_jj^-1 H_jp`` (a small
dense solve per landmark), and the pose marginals are the diagonal (6, 6) blocks of
``S^-1`` (one dense Cholesky inversion, LAPACK ``potrf``/``potri``). Why not the Bayes
tree's ``marginalCovariance`` per pose (:func:`planodom.smoothing.batch.pose_covariances`):
each call walks the tree from the pose's clique to the root, and with many landmarks and a
closed loop that walk is long; measured on a 32-beam lidar lap with loop closure (632
epochs, 50 planes an epoch, a loaded 2-core machine) the Bayes tree took 75 s, this 3 s
(the same covariances to 1e-7 of their norms). The dense inversion grows with the cube of
the number of poses: with few landmarks the Bayes tree is faster (:func:`schur_preferred`).
"""

from __future__ import annotations

from collections.abc import Sequence

import gtsam
import numpy as np
from scipy.linalg import lapack

POSE_DIM = 6


def schur_preferred(n_poses: int, dims: dict[int, int]) -> bool:
    """Whether :func:`pose_marginals` is the faster way: when the landmarks hold more
    dimensions than the poses (``dims`` of all variables, poses among them). The dense
    inversion grows with the cube of the poses' dimension, the Bayes tree's walks with
    the landmarks. Measured (loaded 2-core machine): a 32-beam lidar lap, 632 epochs and
    about 4 times more landmark than pose dimensions: 3 s against 75 s; a 2D-rig run of
    2 000 epochs with a few landmarks an epoch: 80 s against 5 s."""
    total = sum(dims.values())
    return total - POSE_DIM * n_poses > POSE_DIM * n_poses


def _groups(linear: gtsam.GaussianFactorGraph, pose_index: dict[int, int]) -> dict[int, int]:
    """Non-pose key -> its group's root: keys joined by a factor are one group."""
    parent: dict[int, int] = {}

    def find(key: int) -> int:
        while parent[key] != key:
            parent[key] = parent[parent[key]]
            key = parent[key]
        return key

    for i in range(linear.size()):
        factor = linear.at(i)
        if factor is None:
            continue
        others = [key for key in factor.keys() if key not in pose_index]
        for key in others:
            parent.setdefault(key, key)
        for key in others[1:]:
            parent[find(key)] = find(others[0])
    return {key: find(key) for key in parent}


def pose_marginals(
    linear: gtsam.GaussianFactorGraph, pose_keys: Sequence[int], dims: dict[int, int]
) -> np.ndarray:
    """(E, 6, 6) marginal covariances of the Pose3 variables ``pose_keys`` of ``linear``.

    Args:
        linear: the linearised graph (every variable determined).
        pose_keys: the E pose keys, in output order.
        dims: tangent dimension of every other key in ``linear``.

    Raises:
        numpy.linalg.LinAlgError: a landmark's block or the poses' Schur complement is
            not positive definite (an undetermined variable).
    """
    pose_index = {key: i for i, key in enumerate(pose_keys)}
    n = POSE_DIM * len(pose_keys)
    S = np.zeros((n, n))
    group_of = _groups(linear, pose_index)
    by_group: dict[int, list[gtsam.GaussianFactor]] = {}
    for i in range(linear.size()):
        factor = linear.at(i)
        if factor is None:
            continue
        keys = list(factor.keys())
        others = [key for key in keys if key not in pose_index]
        if others:
            by_group.setdefault(group_of[others[0]], []).append(factor)
            continue
        info = factor.information()
        cols = np.concatenate([POSE_DIM * pose_index[k] + np.arange(POSE_DIM) for k in keys])
        S[np.ix_(cols, cols)] += info
    for factors in by_group.values():
        _eliminate_group(factors, pose_index, dims, S)
    chol, info = lapack.dpotrf(S, lower=False, overwrite_a=True)
    if info != 0:
        raise np.linalg.LinAlgError(f"pose information not positive definite ({info})")
    cov, info = lapack.dpotri(chol, lower=False, overwrite_c=True)
    if info != 0:
        raise np.linalg.LinAlgError(f"pose information not invertible ({info})")
    blocks = np.stack([cov[i : i + POSE_DIM, i : i + POSE_DIM] for i in range(0, n, POSE_DIM)])
    # potri fills the upper triangle only: mirror it within each block
    upper = np.triu(np.ones((POSE_DIM, POSE_DIM), dtype=bool))
    return np.where(upper, blocks, np.swapaxes(blocks, 1, 2))


def _eliminate_group(
    factors: list[gtsam.GaussianFactor],
    pose_index: dict[int, int],
    dims: dict[int, int],
    S: np.ndarray,
) -> None:
    """Add one landmark's factors to the poses' information ``S`` with the landmark's
    variables eliminated (its Schur complement), in place."""
    local: dict[int, int] = {}  # key -> offset in the local matrix, landmark keys first
    for factor in factors:
        for key in factor.keys():
            if key not in pose_index and key not in local:
                local[key] = sum(dims[k] for k in local)
    m = sum(dims[k] for k in local)
    poses = sorted(
        {k for f in factors for k in f.keys() if k in pose_index}, key=pose_index.__getitem__
    )
    for key in poses:
        local[key] = m + POSE_DIM * poses.index(key)
    size = m + POSE_DIM * len(poses)
    H = np.zeros((size, size))
    for factor in factors:
        cols = np.concatenate(
            [local[k] + np.arange(POSE_DIM if k in pose_index else dims[k]) for k in factor.keys()]
        )
        H[np.ix_(cols, cols)] += factor.information()
    H_ll, H_lp, H_pp = H[:m, :m], H[:m, m:], H[m:, m:]
    reduced = H_pp - H_lp.T @ np.linalg.solve(H_ll, H_lp)
    cols = np.concatenate([POSE_DIM * pose_index[k] + np.arange(POSE_DIM) for k in poses])
    S[np.ix_(cols, cols)] += reduced
