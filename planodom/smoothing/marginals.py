"""Pose marginals of a linearised smoothing graph by the Schur complement on the landmarks.

Every landmark's variables (an anchored landmark's anchor ``A(j)`` and plane ``L(j)``, or a
global landmark's ``L(j)``) share factors only with each other and with poses: the
information matrix, ordered poses first, is

    H = [[H_pp, H_pl], [H_lp, H_ll]],  H_ll block diagonal (one block per landmark),

so the poses' marginal information is ``S = H_pp - sum_j H_pj H_jj^-1 H_jp`` (a small
dense solve per landmark), and the pose marginals are the diagonal (6, 6) blocks of
``S^-1`` (one dense Cholesky inversion, LAPACK ``potrf``/``potri``). Why not the Bayes
tree's ``marginalCovariance`` per pose (:func:`pose_covariances`):
each call walks the tree from the pose's clique to the root, and with many landmarks and a
closed loop that walk is long; measured on a 32-beam lidar lap with loop closure (632
epochs, 50 planes an epoch, a loaded 2-core machine) the Bayes tree took 75 s, this 3 s
(the same covariances to 1e-7 of their norms). The dense inversion grows with the cube of
the number of poses: with few landmarks the Bayes tree is faster (:func:`schur_preferred`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import gtsam
import numpy as np
from scipy.linalg import lapack, solve_triangular

from planodom.smoothing.graph import F, X

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
    n = POSE_DIM * len(pose_keys)
    S = pose_information(linear, pose_keys, dims)
    chol, info = lapack.dpotrf(S, lower=False, overwrite_a=True)
    if info != 0:
        raise np.linalg.LinAlgError(f"pose information not positive definite ({info})")
    cov, info = lapack.dpotri(chol, lower=False, overwrite_c=True)
    if info != 0:
        raise np.linalg.LinAlgError(f"pose information not invertible ({info})")
    return _blocks(cov, n)


def pose_information(
    linear: gtsam.GaussianFactorGraph,
    pose_keys: Sequence[int],
    dims: dict[int, int],
    dropped: list[int] | None = None,
) -> np.ndarray:
    """(6E, 6E) the poses' information, every other variable eliminated (their Schur
    complement, one landmark group at a time). ``dropped``: None, a landmark group's
    block must be invertible (else LinAlgError); a list, its undetermined directions
    are left out (:func:`_reduce_determined`) and the keys they involve appended."""
    pose_index = {key: i for i, key in enumerate(pose_keys)}
    n = POSE_DIM * len(pose_keys)
    S = np.zeros((n, n))
    pose_only, by_group = split_factors(linear, pose_index)
    for i in pose_only:
        factor = linear.at(i)
        cols = pose_columns(factor.keys(), pose_index)
        S[np.ix_(cols, cols)] += factor.information()
    for members in by_group.values():
        _eliminate_group([linear.at(i) for i in members], pose_index, dims, S, dropped)
    return S


def split_factors(
    linear: gtsam.GaussianFactorGraph, pose_index: dict[int, int]
) -> tuple[list[int], dict[int, list[int]]]:
    """The indices of ``linear``'s factors on poses only, and of the others by landmark
    group (:func:`_groups`; a group's factors in index order)."""
    group_of = _groups(linear, pose_index)
    pose_only: list[int] = []
    by_group: dict[int, list[int]] = {}
    for i in range(linear.size()):
        factor = linear.at(i)
        if factor is None:
            continue
        others = [key for key in factor.keys() if key not in pose_index]
        if others:
            by_group.setdefault(group_of[others[0]], []).append(i)
        else:
            pose_only.append(i)
    return pose_only, by_group


def pose_columns(keys: Sequence[int], pose_index: dict[int, int]) -> np.ndarray:
    """The columns of the poses ``keys`` in the poses' information (6 each)."""
    return np.concatenate([POSE_DIM * pose_index[k] + np.arange(POSE_DIM) for k in keys])


def _blocks(cov: np.ndarray, n: int) -> np.ndarray:
    """The (6, 6) diagonal blocks of a ``potri`` inverse (upper triangle filled)."""
    blocks = np.stack([cov[i : i + POSE_DIM, i : i + POSE_DIM] for i in range(0, n, POSE_DIM)])
    # potri fills the upper triangle only: mirror it within each block
    upper = np.triu(np.ones((POSE_DIM, POSE_DIM), dtype=bool))
    return np.where(upper, blocks, np.swapaxes(blocks, 1, 2))


def local_layout(
    factors: list[gtsam.GaussianFactor], pose_index: dict[int, int], dims: Mapping[int, int]
) -> tuple[dict[int, int], int, list[int], int]:
    """The local matrix of one landmark group's ``factors``: ``(local, m, poses, size)``,
    ``local`` each key's offset (the landmark keys first, their ``dims``, then the poses
    in ``pose_index`` order, 6 each), ``m`` the landmarks' dimension, ``poses`` the pose
    keys in order, ``size`` the whole dimension."""
    local: dict[int, int] = {}
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
    return local, m, poses, m + POSE_DIM * len(poses)


def _eliminate_group(
    factors: list[gtsam.GaussianFactor],
    pose_index: dict[int, int],
    dims: dict[int, int],
    S: np.ndarray,
    dropped: list[int] | None = None,
) -> None:
    """Add one landmark's factors to the poses' information ``S`` with the landmark's
    variables eliminated (its Schur complement), in place; ``dropped``: see
    :func:`pose_information`."""
    local, m, poses, size = local_layout(factors, pose_index, dims)
    H = np.zeros((size, size))
    for factor in factors:
        cols = np.concatenate(
            [local[k] + np.arange(POSE_DIM if k in pose_index else dims[k]) for k in factor.keys()]
        )
        H[np.ix_(cols, cols)] += factor.information()
    H_ll, H_lp, H_pp = H[:m, :m], H[:m, m:], H[m:, m:]
    if dropped is None:
        reduced = H_pp - H_lp.T @ np.linalg.solve(H_ll, H_lp)
    else:
        reduced = H_pp - _reduce_determined(H_ll, H_lp, list(local)[: len(local) - len(poses)],
                                            dims, dropped)  # fmt: skip
    cols = pose_columns(poses, pose_index)
    S[np.ix_(cols, cols)] += reduced


#: Undetermined: a direction whose information, relative to the largest of its block
#: after scaling every variable to unit diagonal (Jacobi), is below this. Double
#: precision resolves about 1e-16 of the largest; the 2D-rig laps' weakest determined
#: direction (pose heights bridged only by the vertical random walk) is 1e-11.
UNDETERMINED_RTOL = 1e-13


def _reduce_determined(
    H_ll: np.ndarray, H_lp: np.ndarray, keys: list[int], dims: dict[int, int], dropped: list[int]
) -> np.ndarray:
    """``H_lp^T H_ll^+ H_lp`` with ``H_ll^+`` the inverse on the determined directions of
    the Jacobi-scaled ``H_ll``: a direction ``u`` the factors do not determine
    (``H_ll u = 0``) carries no information on the poses either (``H_lp^T u = 0``, the
    information being positive semi-definite), so leaving it out is the exact
    marginalisation of the rest. Keys ``keys`` (in ``H_ll``'s order) spanning such a
    direction are appended to ``dropped``."""
    d = np.sqrt(np.diag(H_ll))
    d[d == 0.0] = 1.0
    w, V = np.linalg.eigh(H_ll / np.outer(d, d))
    keep = w > UNDETERMINED_RTOL * max(float(w[-1]), 1.0)
    if not keep.all():
        offsets = np.cumsum([0] + [dims[k] for k in keys])
        free = np.abs(V[:, ~keep]).max(axis=1) > 1e-3
        dropped += [k for i, k in enumerate(keys) if free[offsets[i] : offsets[i + 1]].any()]
    B = V[:, keep].T @ (H_lp / d[:, None])
    return B.T @ (B / w[keep, None])


@dataclass
class DeterminedMarginals:
    """Pose marginals with what the graph leaves undetermined named.

    Attributes:
        covariances: (E, 6, 6) as :func:`pose_marginals`; rows and columns of a pose's
            undetermined tangent axes NaN.
        dropped: non-pose keys with a direction no factor determines (left out: it does
            not inform the poses).
        undetermined: pose index -> its tangent axes (0-2 rotation, 3-5 translation)
            that the graph does not determine.
    """

    covariances: np.ndarray
    dropped: list[int]
    undetermined: dict[int, list[int]]


def determined_pose_marginals(
    linear: gtsam.GaussianFactorGraph, pose_keys: Sequence[int], dims: dict[int, int]
) -> DeterminedMarginals:
    """The pose marginals of :func:`pose_marginals`, by LAPACK on the Jacobi-scaled
    information, for graphs gtsam refuses or with undetermined variables.

    Why: gtsam's multifrontal elimination refuses some positive definite but multi-scale
    systems (IndeterminantLinearSystemException, with Cholesky and with QR): on four of
    the ten 2D-rig laps at 6 mm with loop closure, the pose heights along stretches
    without a floor or ceiling track are determined only by the vertical random walk
    (sigma up to 0.44 m; smallest eigenvalue of the information 8e-3, its diagonal
    1e3 to 1e16) next to mm-level horizontal positions; gtsam names a different variable
    with each ordering (METIS a30 or x1053, COLAMD l33, natural x1359) and succeeds
    sequentially in the natural order, while LAPACK's Cholesky of the same information
    succeeds (residual of the inverse 2e-10; world 4's sigmas from here within 1e-6 of a
    dense inverse of the whole information).

    Undetermined directions: a landmark group's are left out exactly
    (:func:`_reduce_determined`); the poses' information is factored by pivoted
    Cholesky (``pstrf``, rank at ``UNDETERMINED_RTOL``), its null space ``N``
    (orthonormal) found, and ``S + N N^T`` inverted: the same covariance for every
    determined combination of the poses; the axes ``N`` touches are set NaN.
    """
    n = POSE_DIM * len(pose_keys)
    dropped: list[int] = []
    S = pose_information(linear, pose_keys, dims, dropped)
    d = np.sqrt(np.diag(S))
    d[d == 0.0] = 1.0
    S /= np.outer(d, d)
    undetermined: dict[int, list[int]] = {}
    chol, info = lapack.dpotrf(S, lower=False)
    if info != 0:
        tol = UNDETERMINED_RTOL * float(np.max(np.diag(S)))
        U, piv, rank, _ = lapack.dpstrf(S, tol=tol, lower=False)
        perm = piv - 1  # LAPACK's pivots are 1-based
        U11, U12 = np.triu(U[:rank, :rank]), U[:rank, rank:]
        null = np.zeros((n, n - rank))
        null[perm[:rank]] = -solve_triangular(U11, U12)
        null[perm[rank:]] = np.eye(n - rank)
        Q, _ = np.linalg.qr(null)
        free = (Q**2).sum(axis=1) > 1e-9
        for i in np.flatnonzero(free):
            undetermined.setdefault(int(i) // POSE_DIM, []).append(int(i) % POSE_DIM)
        chol, info = lapack.dpotrf(S + Q @ Q.T, lower=False)
        if info != 0:
            raise np.linalg.LinAlgError(f"pose information not positive definite ({info})")
    # S^-1 = U^-1 U^-T: each pose's block from its rows of U^-1 (a third less than potri)
    inverse, info = lapack.dtrtri(np.triu(chol), lower=False, overwrite_c=True)
    if info != 0:
        raise np.linalg.LinAlgError(f"pose information not invertible ({info})")
    rows = inverse.reshape(len(pose_keys), POSE_DIM, n)
    blocks = np.einsum("kin,kjn->kij", rows, rows)
    scale = d.reshape(len(pose_keys), POSE_DIM)
    blocks /= scale[:, :, None] * scale[:, None, :]
    for pose, axes in undetermined.items():
        blocks[pose][axes, :] = np.nan
        blocks[pose][:, axes] = np.nan
    return DeterminedMarginals(blocks, sorted(set(dropped)), undetermined)


#: For covariances relative to the first pose: its prior's sigma is divided by this.
FIRST_POSE_TIGHTENING = 1e4


#: The dense fallback's largest pose system (dimensions; 1 500 epochs of 6): it holds a
#: few dense copies of it, 8 n^2 bytes each (650 MB at this size), and takes about the
#: cube of n in time (world 4's 8 190 dimensions: about 50 s on a loaded 2-core
#: machine). A resource limit, not fitted to a run: beyond it the covariances are
#: reported unavailable, as before the fallback.
DENSE_MAX_POSE_DIM = 9000


def pose_covariances(
    graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    n_epochs: int,
    relative_to_first: bool = False,
    prior_sigma: float = 1e-4,
    linear: gtsam.GaussianFactorGraph | None = None,
) -> tuple[np.ndarray, str | None]:
    """(E, 6, 6) marginal covariances of ``X(0..E-1)`` at ``values``, and a note naming
    what the graph leaves undetermined (None when nothing).

    From a Bayes tree (Cholesky, METIS ordering), or the same from a QR elimination when
    Cholesky finds the system indeterminant (see :func:`.batch.levenberg_marquardt`); when both
    fail, by LAPACK on the Jacobi-scaled Schur complement
    (:func:`determined_pose_marginals`): gtsam's elimination refuses some
    positive definite but multi-scale systems, and there an undetermined variable that
    does not inform the poses is left out, and a pose's undetermined axes are NaN and
    named in the note (the covariances computed before by a Bayes tree are unchanged).

    With ``relative_to_first`` the covariances are conditioned on the first pose: a
    prior ``FIRST_POSE_TIGHTENING`` times stiffer than the gauge prior (sigma
    ``prior_sigma``) is added to ``X(0)`` in the linearised graph. That is the
    covariance of ``X(0)^-1 X(k)`` (checked against the exact joint marginals of X(0) and
    X(k) to 1e-6 of the standard deviations on the paper loop, where those cost 100 times
    more), without the gauge prior's uncertainty: a rotation of ``prior_sigma`` rad of
    the first pose would add ``prior_sigma`` times the distance to every translation
    sigma (2 mm at 20 m, more than the smoothed error at 6 mm range noise).

    ``linear``: the linearised graph to take them from (reweighted by
    ``smoothing.covariance_scale``, :mod:`.variance_components`); default ``graph``'s.
    """
    linear = graph.linearize(values) if linear is None else linear
    if relative_to_first:
        stiff = FIRST_POSE_TIGHTENING / prior_sigma
        linear.add(X(0), stiff * np.eye(6), np.zeros(6), gtsam.noiseModel.Unit.Create(6))
    zero = values.zeroVectors()
    dims = {key: zero.at(key).size for key in values.keys()}
    # Deskewed frames join every landmark an epoch sees: eliminated with the poses, else
    # the landmarks would make one group (a dense block of all of them).
    frames = [F(k) for k in range(n_epochs) if values.exists(F(k))]
    if schur_preferred(n_epochs + len(frames), dims):  # many landmarks (.marginals)
        try:
            keys = [X(k) for k in range(n_epochs)] + frames
            return pose_marginals(linear, keys, dims)[:n_epochs], None
        except np.linalg.LinAlgError:  # an undetermined direction: the Bayes tree with QR
            pass
    # METIS (nested dissection), not gtsam.Marginals' COLAMD: a closed loop joins the
    # lap's ends, and each pose's marginal walks the Bayes tree to its root; measured on
    # a 32-beam lidar lap with loop closure (632 epochs): 44 s with COLAMD, 25 s with
    # METIS, the same covariances to 2e-10.
    ordering = gtsam.Ordering.MetisNonlinearFactorGraph(graph)
    try:
        tree = linear.eliminateMultifrontal(ordering)  # Cholesky
        return np.stack([tree.marginalCovariance(X(k)) for k in range(n_epochs)]), None
    except RuntimeError:
        pass
    try:
        tree = linear.eliminateMultifrontal(ordering, gtsam.EliminateQR)
        return np.stack([_qr_marginal(tree, X(k)) for k in range(n_epochs)]), None
    except RuntimeError:
        pass
    keys = [X(k) for k in range(n_epochs)] + frames
    pose_dim = sum(dims[k] for k in keys)
    if pose_dim > DENSE_MAX_POSE_DIM:
        raise RuntimeError(
            f"gtsam found the system indeterminant, and its {pose_dim} pose dimensions are "
            f"over the dense fallback's {DENSE_MAX_POSE_DIM}"
        )
    marginals = determined_pose_marginals(linear, keys, dims)
    return marginals.covariances[:n_epochs], undetermined_note(marginals, n_epochs)


def _qr_marginal(tree: gtsam.GaussianBayesTree, key: int) -> np.ndarray:
    """(d, d) marginal covariance of ``key`` from a QR Bayes tree: gtsam's, whose shortcuts
    eliminate by Cholesky; where that refuses a clique (gtsam's check of each pivot against
    its variable's assembled diagonal, :mod:`.linear_solve`), the shortcuts by QR too."""
    try:
        return tree.marginalCovariance(key)
    except RuntimeError:
        R, _ = tree.marginalFactor(key, gtsam.EliminateQR).jacobian()  # whitened, d x d
        R_inv = np.linalg.inv(R)
        return R_inv @ R_inv.T


def undetermined_note(marginals: DeterminedMarginals, n_epochs: int) -> str | None:
    """What :func:`pose_covariances` found undetermined, in words (None: nothing)."""
    parts = []
    if marginals.dropped:
        names = [gtsam.DefaultKeyFormatter(k) for k in marginals.dropped]
        parts.append("left out (undetermined, no information on the poses): " + ", ".join(names))
    poses = {k: a for k, a in marginals.undetermined.items() if k < n_epochs}
    if poses:
        epochs = ", ".join(f"{k} (axes {a})" for k, a in sorted(poses.items()))
        parts.append("undetermined pose axes, covariance NaN there: epochs " + epochs)
    frames = len(marginals.undetermined) - len(poses)
    if frames:
        parts.append(f"{frames} deskewed frames with undetermined axes")
    return "; ".join(parts) or None
