"""Sandwich (misspecified-model) covariances of the batch poses: the deskewing error.

The batch estimate minimises the whitened residuals of the graph's noise models. At the
solution, with ``J`` the whitened Jacobian of the linearised graph and ``A = J^T J`` its
information, the fitted covariance is ``A^-1``: right if the whitened measurements' error
has covariance ``I``. Scans spread in time are deskewed with the twist of the previous
interval, and the change of motion ``dxi_k`` over epoch k (twist, per epoch span) moves
every plane of that epoch through its own first-order change with the deskewing twist
(``Plane.deskew_jacobian``, (4, 6)): one error shared by all the epoch's planes, which
each pose takes whole and no residual shows (``config.smoothing.covariance_scale``). The
whitened measurements' error is then ``I + S``, ``S = G Q G^T``: per epoch k a (6, 6)
covariance ``Q_k`` of ``dxi_k`` (:meth:`.DeskewNoise.plane_motion_change`, from the run's
own changes of motion) and ``G`` mapping it to each plane factor of that epoch (its
whitening times the plane's Jacobian in the factor's error coordinates). The estimator's
covariance (the same estimate) is

    Cov(x) = A^-1 J^T (I + S) J A^-1 = A^-1 + C Q C^T,   C = A^-1 J^T G.

Only the poses' diagonal blocks are wanted. With the landmarks eliminated as for the
fitted marginals (:mod:`.marginals`: the poses' Schur complement ``P``, one landmark group
at a time), the pose rows of ``A^-1 B`` (``B = J^T G``) are ``P^-1 B~`` with
``B~ = B_p - H_pl H_ll^+ B_l``; so with ``Sigma = P^-1`` (one dense inversion, as the
fitted path's) the pose block i is ``Sigma_ii + sum_k (Sigma B~)_ik Q_k (Sigma B~)_ik^T``.
``B~`` is sparse (an epoch's columns reach the poses that share its landmarks).

Optionally (``SELECTED_INVERSION``, off) without forming ``Sigma``: the pose blocks of
``Sigma`` and of ``Sigma B~ Q B~^T Sigma = -d/de (P + e B~ Q B~^T)^-1`` are what a sparse
selected inversion (Takahashi's recursion over supernodes) and its exact derivative give
(:func:`_sparse_pose_covariances`); the dense path (:func:`_dense_pose_covariances`)
is the default and remains for poses with undetermined axes.

Not modelled: the deskewing error of the relative-pose and loop-candidate factors (they
enter only where planes are not plane factors, ``smoothing.between_factors``) and of
factors the robust kernel down-weights at the estimate (outliers of
:func:`.batch.covariance_graph`); both would only add.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import gtsam
import gtsam_unstable
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.linalg import lapack, solve_triangular

from planodom.config import SmoothingConfig
from planodom.geometry import Plane
from planodom.odometry.relative import RelativePose
from planodom.smoothing.deskew_noise import DeskewNoise
from planodom.smoothing.graph import X
from planodom.smoothing.marginals import (
    FIRST_POSE_TIGHTENING,
    POSE_DIM,
    UNDETERMINED_RTOL,
    local_layout,
    pose_columns,
    split_factors,
)

#: ``OrientedPlane3::errorVector``'s first-order change with the measured plane's tangent
#: coordinates ``delta`` (Unit3 basis (2), d) is ``sign * diag(1, 1, -1) delta`` at a
#: vanishing residual: +1 for the global factor, -1 for the anchored one (which takes the
#: difference the other way round; checked numerically in tests/smoothing/test_sandwich.py).
ERROR_SIGN = {gtsam.OrientedPlane3Factor: 1.0, gtsam_unstable.LocalOrientedPlane3Factor: -1.0}

#: Pose rows per chunk of ``Sigma B~`` (memory: chunk times the poses' dimension).
CHUNK_ROWS = 1200

#: ``B~`` is multiplied in dense form (BLAS) when more than this share of it is non-zero
#: (a ground plane seen by every epoch fills it; scipy's sparse product is single-threaded
#: and several times slower per non-zero than a dense one).
DENSE_FRACTION = 0.1


def plane_error_map(factor: gtsam.NonlinearFactor, plane: Plane) -> np.ndarray | None:
    """(3, 6) first-order change of a plane factor's whitened error with its epoch's change
    of motion ``dxi`` (rotation (rad), translation (m) per epoch span), through the
    measured ``plane``'s ``deskew_jacobian`` (as oriented in the factor); None for a plane
    without it or a factor whose noise model is not Gaussian (a robust outlier)."""
    if plane.deskew_jacobian is None:
        return None
    sign = next((s for t, s in ERROR_SIGN.items() if isinstance(factor, t)), None)
    noise = factor.noiseModel()  # type: ignore[attr-defined]  # a NoiseModelFactor
    if sign is None or not isinstance(noise, gtsam.noiseModel.Gaussian):
        return None
    P = np.zeros((3, 4))  # (n, d) -> tangent, as plane_tangent_covariance
    P[:2, :3] = np.asarray(gtsam.Unit3(plane.normal).basis()).T
    P[2, 3] = 1.0
    tangent = P @ np.asarray(plane.deskew_jacobian, dtype=float)
    tangent[2] *= -1.0  # errorVector's offset part (planodom_factors.planes.plane_noise)
    return sign * np.asarray(noise.R()) @ tangent


@dataclass
class SandwichMarginals:
    """Pose covariances of :func:`sandwich_pose_covariances`.

    Attributes:
        covariances: (E, 6, 6) the sandwich covariances (NaN on undetermined axes).
        fitted: (E, 6, 6) ``A^-1``'s blocks from the same factorisation (the fitted ones).
        undetermined: pose index -> its tangent axes the graph does not determine.
        columns: plane factors that carried a deskewing error into ``S``.
    """

    covariances: np.ndarray
    fitted: np.ndarray
    undetermined: dict[int, list[int]]
    columns: int


def sandwich_pose_covariances(
    linear: gtsam.GaussianFactorGraph,
    pose_keys: Sequence[int],
    dims: Mapping[int, int],
    error_maps: Mapping[int, tuple[int, np.ndarray]],
    motion_change: np.ndarray,
) -> SandwichMarginals:
    """The poses' sandwich covariances (module docstring) of a linearised graph.

    By the dense path (:func:`_dense_pose_covariances`); with ``SELECTED_INVERSION`` by
    a sparse selected inversion (:func:`_sparse_pose_covariances`), the dense path
    taking over where that meets a pivot at the undetermined level.

    Args:
        linear: the linearised (whitened) graph at the estimate.
        pose_keys: the E pose keys, in output order.
        dims: tangent dimension of every key of ``linear``.
        error_maps: index of a factor in ``linear`` -> (its epoch column k, (m, 6) change
            of its whitened error with ``dxi_k``, m its dimension).
        motion_change: (K, 6, 6) ``Q_k``, the covariance of ``dxi_k`` per epoch column.

    Raises:
        numpy.linalg.LinAlgError: the poses' information is not positive definite even on
            its determined directions.
    """
    if not SELECTED_INVERSION:
        return _dense_pose_covariances(linear, pose_keys, dims, error_maps, motion_change)
    try:
        covariances, fitted = _sparse_pose_covariances(
            linear, pose_keys, dims, error_maps, motion_change
        )
    except _NotDefinite:
        return _dense_pose_covariances(linear, pose_keys, dims, error_maps, motion_change)
    return SandwichMarginals(covariances, fitted, {}, len(error_maps))


def _dense_pose_covariances(
    linear: gtsam.GaussianFactorGraph,
    pose_keys: Sequence[int],
    dims: Mapping[int, int],
    error_maps: Mapping[int, tuple[int, np.ndarray]],
    motion_change: np.ndarray,
) -> SandwichMarginals:
    """:func:`sandwich_pose_covariances` by the poses' dense Schur complement: one dense
    inversion, undetermined pose axes found by pivoted Cholesky and set NaN."""
    pose_index = {key: i for i, key in enumerate(pose_keys)}
    n = POSE_DIM * len(pose_keys)
    S = np.zeros((n, n))
    parts: list[tuple[np.ndarray, dict[int, int], np.ndarray]] = []  # B~'s blocks

    def add_block(pose_cols: np.ndarray, col_of: dict[int, int], block: np.ndarray) -> None:
        parts.append((pose_cols, dict(col_of), block))

    pose_only, by_group = split_factors(linear, pose_index)
    for i in pose_only:
        factor = linear.at(i)
        A = factor.jacobian()[0]
        pcols = pose_columns(factor.keys(), pose_index)
        S[np.ix_(pcols, pcols)] += A.T @ A
        if i in error_maps:
            k, g = error_maps[i]
            add_block(pcols, {k: 0}, A.T @ g)
    for members in by_group.values():
        _eliminate(linear, members, pose_index, dims, error_maps, S, add_block)
    sigma, d, undetermined = _scaled_inverse(S)
    del S
    # Q_k = L_k L_k^T folded into B~'s columns: the extra term's block i is then
    # (Sigma B~ L)_i (Sigma B~ L)_i^T, one batched product per chunk of poses.
    roots = [_psd_root(q) for q in np.asarray(motion_change, dtype=float)]
    Bs = _scaled_columns(parts, n, roots, 1.0 / d)
    E = len(pose_keys)
    fitted, extra = _pose_blocks(sigma, Bs)
    scale = d.reshape(E, POSE_DIM)
    outer = scale[:, :, None] * scale[:, None, :]
    fitted /= outer
    covariances = fitted + extra / outer
    for pose, axes in undetermined.items():
        for blocks in (covariances, fitted):
            blocks[pose][axes, :] = np.nan
            blocks[pose][:, axes] = np.nan
    return SandwichMarginals(covariances, fitted, undetermined, len(error_maps))


class _NotDefinite(Exception):
    """The sparse factorisation met a pivot at or below the undetermined level: the dense
    path (pivoted Cholesky, undetermined axes named) takes over."""


#: Relaxed supernodes of :func:`_selected_inverse`: a supernode is merged with its
#: parent while the merged block's dense panel holds at most this many times their
#: entries, or is at most ``MERGE_WIDTH`` columns wide.
MERGE_PADDING = 2.0
MERGE_WIDTH = 24

#: The widest block of :func:`_selected_inverse` (columns): wider supernodes are split.
#: Its products run in numpy's own loops (:func:`_mm`), fast up to about this size.
NODE_WIDTH = 48

#: Off: the sparse selected inversion is 1.2-7 times faster than the dense path on the
#: 2D-rig laps, and equal to it to 3e-11 (worlds 8, 14) or 4e-6 (6, 18) of the standard
#: deviations, but on the worse conditioned laps it differs by 6e-5 (world 0 at 2 cm)
#: and 1e-3 (world 2 at 6 mm), where the dense path and gtsam agree to 5e-8 and 3e-7
#: (docs/RESULTS.md, SANDFAST; with one-column blocks world 2's fitted blocks are at
#: round-off, its sandwich term not): not explained yet, so not the default.
SELECTED_INVERSION = False

#: Diagnostic: the selected inversion on the poses' sparse Schur complement instead of
#: the system with the landmarks' determined directions (the same differences).
POSE_SPACE = False


def _sparse_pose_covariances(
    linear: gtsam.GaussianFactorGraph,
    pose_keys: Sequence[int],
    dims: Mapping[int, int],
    error_maps: Mapping[int, tuple[int, np.ndarray]],
    motion_change: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """(E, 6, 6) twice, the sandwich and the fitted pose blocks, by a sparse selected
    inversion.

    The poses' Schur complement ``P`` (dense when a landmark is seen from everywhere) is
    not formed: each landmark group's determined directions become variables ``y`` of
    unit information (``H_ll^+ = D^-1 W W^T D^-1`` as in the dense path, ``y = W^T D l``)
    in the sparse system ``K = [[H_pp, C^T], [C, I]]`` (``C = W^T D^-1 H_lp``; its Schur
    complement on the poses is ``P``), with the columns ``R = [B_p; W^T D^-1 B_l]
    blockdiag(L_k)`` (``Q_k = L_k L_k^T``), whose pose rows of ``K^-1 R`` are ``P^-1 B~
    L``. So the fitted blocks are the pose blocks of ``K^-1``, the sandwich's extra term
    those of ``K^-1 R R^T K^-1 = -d/de (K + e R R^T)^-1``: both from one selected
    inversion carried with its derivative (:func:`_selected_inverse`), on the Jacobi-scaled
    system. The whitened Jacobian is gathered once into a sparse matrix (no loop over a
    group's factors in Python).

    Raises:
        _NotDefinite: a pivot of the Jacobi-scaled ``K`` is not above
            ``UNDETERMINED_RTOL`` of its largest diagonal entry (an undetermined pose axis).
    """
    pose_index = {key: i for i, key in enumerate(pose_keys)}
    E = len(pose_keys)
    n = POSE_DIM * E
    pose_only, by_group = split_factors(linear, pose_index)
    offset: dict[int, int] = {}  # landmark key -> its column among the landmarks'
    groups: list[tuple[int, int]] = []  # each group's landmark columns [start, stop)
    m_all = 0
    for members in by_group.values():
        start = m_all
        for i in members:
            for key in linear.at(i).keys():
                if key not in pose_index and key not in offset:
                    offset[key] = m_all
                    m_all += dims[key]
        groups.append((start, m_all))
    col_of = {key: POSE_DIM * i for key, i in pose_index.items()}
    col_of |= {key: n + c for key, c in offset.items()}
    # The whitened Jacobian J and the error maps G (rows: the factors' rows in order).
    rows, cols, vals, g_rows, g_cols, g_vals = [], [], [], [], [], []
    row = 0
    for i in sorted(pose_only + [i for members in by_group.values() for i in members]):
        factor = linear.at(i)
        A = factor.jacobian()[0]
        keys = factor.keys()
        c = np.concatenate(
            [col_of[k] + np.arange(POSE_DIM if k in pose_index else dims[k]) for k in keys]
        )
        r = row + np.arange(A.shape[0])
        rows.append(np.repeat(r, len(c)))
        cols.append(np.tile(c, len(r)))
        vals.append(A.ravel())
        if i in error_maps:
            k, g = error_maps[i]
            g_rows.append(np.repeat(r, POSE_DIM))
            g_cols.append(np.tile(POSE_DIM * k + np.arange(POSE_DIM), len(r)))
            g_vals.append(np.asarray(g, dtype=float).ravel())
        row += A.shape[0]
    N_all = n + m_all
    K_count = len(motion_change)
    J = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(row, N_all)
    )
    if g_vals:
        G = sp.csr_matrix(
            (np.concatenate(g_vals), (np.concatenate(g_rows), np.concatenate(g_cols))),
            shape=(row, POSE_DIM * K_count),
        )
    else:
        G = sp.csr_matrix((row, POSE_DIM * K_count))
    Jt = J.T.tocsr()
    H = (Jt @ J).tocsr()
    B = (Jt @ G).tocsr()
    # Each group's determined directions (as _eliminate / marginals._reduce_determined).
    blocks = []
    for start, stop in groups:
        H_ll = H[n + start : n + stop, n + start : n + stop].toarray()
        dl = np.sqrt(np.diag(H_ll))
        dl[dl == 0.0] = 1.0
        w, V = np.linalg.eigh(H_ll / np.outer(dl, dl))
        keep = w > UNDETERMINED_RTOL * max(float(w[-1]), 1.0)
        blocks.append((V[:, keep] / np.sqrt(w[keep])) / dl[:, None])  # D^-1 W, (m, r)
    T = sp.block_diag(blocks, format="csr") if blocks else sp.csr_matrix((0, 0))
    R = T.shape[1]
    Tt = T.T.tocsr()
    C = (Tt @ H[n:, :n]).tocsr()  # (R, n)
    if POSE_SPACE:
        K = (H[:n, :n] - C.T @ C).tocsc()
        rhs = (B[:n] - C.T @ (Tt @ B[n:])).tocsr()
    else:
        K = sp.bmat([[H[:n, :n], C.T], [C, sp.identity(R)]], format="csc")
        rhs = sp.vstack([B[:n], Tt @ B[n:]]).tocsr()
    roots = [_psd_root(q) for q in np.asarray(motion_change, dtype=float)]
    rhs = (rhs @ sp.block_diag(roots, format="csr")).tocsc() if roots else rhs.tocsc()
    ds = np.sqrt(K.diagonal())
    ds[ds == 0.0] = 1.0
    Dinv = sp.diags(1.0 / ds)
    Rs = Dinv @ rhs
    # each pose's 6 x 6 block wanted whole (some have structural zeros in K)
    blocks6 = sp.block_diag([np.ones((POSE_DIM, POSE_DIM))] * E, format="csc")
    wanted = sp.block_diag([blocks6, sp.csc_matrix((K.shape[0] - n, K.shape[0] - n))])
    Z, dZ = _selected_inverse(Dinv @ K @ Dinv, (Rs @ Rs.T).tocsc(), wanted)
    pos = Z.position[:n].reshape(E, POSE_DIM)
    fitted = Z.values[pos[:, :, None], pos[:, None, :]]
    extra = -dZ[pos[:, :, None], pos[:, None, :]]
    scale = ds[:n].reshape(E, POSE_DIM)
    outer = scale[:, :, None] * scale[:, None, :]
    return (fitted + extra) / outer, fitted / outer


def _mm(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` by numpy's own loops, not BLAS: the selected inversion's blocks are small
    (tens to a few hundred rows), where OpenBLAS's threads cost more than the product
    and stall when the cores are busy (measured, world 14 at 2 cm: 6-15 s against 1.5 s
    with one BLAS thread)."""
    return np.einsum("ij,jk->ik", a, b)


@dataclass
class _Selected:
    """Entries of a symmetric matrix's inverse on its factor's pattern (dense storage,
    rows and columns in the elimination order: variable i at ``position[i]``)."""

    values: np.ndarray
    position: np.ndarray


def _selected_inverse(
    K: sp.spmatrix, M: sp.spmatrix, wanted: sp.spmatrix
) -> tuple[_Selected, np.ndarray]:
    """``K^-1`` on the pattern of ``K + M + wanted``'s factor (``wanted``: a pattern of
    entries to be computed, e.g. whole diagonal blocks), and there the first-order change
    ``d/de (K + e M)^-1 = -K^-1 M K^-1`` (``K`` (N, N) sparse positive definite, ``M``
    sparse symmetric), both by block elimination over supernodes.

    Block LDL^T of ``K(e)`` (pivot blocks ``P_J``, ``F = K_IJ P_J^-1``, ``K_II -= F
    K_JI``) and Takahashi's selected inversion (``Z_IJ = -Z_II F``, ``Z_JJ = P_J^-1 - F^T
    Z_IJ``, from the last block to the first) on the supernodes' patterns, each carried
    with its derivative in ``e`` (forward-mode, exact: no finite step): the cost of the
    fitted marginals' selected inversion, about twice, instead of ``N`` solves.

    Raises:
        _NotDefinite: a pivot block is not positive definite, or a pivot of its Cholesky
            factor not above ``UNDETERMINED_RTOL`` of the largest diagonal entry.
    """
    N = K.shape[0]
    pattern = (abs(K) + abs(M) + abs(wanted)).tocsc()
    lu = spla.splu(
        pattern + sp.identity(N, format="csc"), permc_spec="MMD_AT_PLUS_A",
        diag_pivot_thresh=0.0, options={"SymmetricMode": True, "Equil": False},
    )  # fmt: skip
    perm = lu.perm_c  # variable i is row perm[i] of the factor
    inv = np.argsort(perm)
    L = lu.L.tocsc()
    L.sort_indices()
    ind, ptr = L.indices, L.indptr
    nodes = _supernodes(ind, ptr, N)
    A = K.tocsr()[inv][:, inv].toarray()
    dA = M.tocsr()[inv][:, inv].toarray()
    top = float(np.max(np.diag(A), initial=1.0))
    factors = []
    for c0, c1, below in nodes:
        J = slice(c0, c1)
        P, dP = A[J, J], dA[J, J]
        try:
            chol = np.linalg.cholesky(P)  # (blocks of at most NODE_WIDTH: see _mm)
        except np.linalg.LinAlgError as exc:
            raise _NotDefinite from exc
        if not np.all(np.diag(chol) ** 2 > UNDETERMINED_RTOL * top):
            raise _NotDefinite
        root = np.linalg.inv(chol)
        Pinv = _mm(root.T, root)
        KJI, dKJI = A[J][:, below], dA[J][:, below]  # (w, |I|)
        F = _mm(Pinv, KJI).T  # K_IJ P^-1, (|I|, w)
        dF = _mm(Pinv, dKJI - _mm(dP, F.T)).T
        if len(below):
            ix = np.ix_(below, below)
            A[ix] -= _mm(F, KJI)
            dA[ix] -= _mm(dF, KJI) + _mm(F, dKJI)
        factors.append((Pinv, dP, F, dF))
    for (c0, c1, below), (Pinv, dP, F, dF) in zip(reversed(nodes), reversed(factors), strict=True):
        J = slice(c0, c1)
        ZJJ = Pinv.copy()
        dZJJ = -_mm(_mm(Pinv, dP), Pinv)
        if len(below):
            ix = np.ix_(below, below)
            ZII, dZII = A[ix], dA[ix]
            ZIJ = -_mm(ZII, F)
            dZIJ = -_mm(dZII, F) - _mm(ZII, dF)
            ZJJ -= _mm(F.T, ZIJ)
            dZJJ -= _mm(dF.T, ZIJ) + _mm(F.T, dZIJ)
            A[below, J], A[J, below] = ZIJ, ZIJ.T
            dA[below, J], dA[J, below] = dZIJ, dZIJ.T
        A[J, J] = 0.5 * (ZJJ + ZJJ.T)
        dA[J, J] = 0.5 * (dZJJ + dZJJ.T)
    return _Selected(A, perm), dA


def _supernodes(ind: np.ndarray, ptr: np.ndarray, N: int) -> list[tuple[int, int, np.ndarray]]:
    """Contiguous column blocks of a factor with sorted CSC pattern (``ind``, ``ptr``,
    diagonal included) and each block's rows below it: fundamental supernodes, merged
    with the next when it is their parent in the elimination tree (its rows then hold
    theirs) while the padded panel holds at most ``MERGE_PADDING`` times their entries
    (or is at most ``MERGE_WIDTH`` wide)."""
    starts = [0]
    for j in range(N - 1):  # a supernode: each column's pattern the last's less one
        a, b = ind[ptr[j] : ptr[j + 1]], ind[ptr[j + 1] : ptr[j + 2]]
        if not (len(a) == len(b) + 1 and np.array_equal(a[1:], b)):
            starts.append(j + 1)
    starts.append(N)
    cuts = []  # supernodes split into blocks of at most NODE_WIDTH columns
    for c0, c1 in zip(starts[:-1], starts[1:], strict=True):
        cuts += list(range(c0, c1, NODE_WIDTH))
    starts = cuts + [N]
    nodes: list[tuple[int, int, np.ndarray]] = []
    entries: list[int] = []
    for c0, c1 in zip(starts[:-1], starts[1:], strict=True):
        below = ind[ptr[c1 - 1] + 1 : ptr[c1]]  # (a supernode's last column's)
        count = int(ptr[c1] - ptr[c0])
        if nodes:  # merged into its child when it is the child's parent (next in order)
            g0, g1, g_below = nodes[-1]
            width = c1 - g0
            padded = width * (width + 1) // 2 + width * len(below)
            cheap = padded <= MERGE_PADDING * (entries[-1] + count) or width <= MERGE_WIDTH
            if len(g_below) and g_below[0] == c0 and width <= NODE_WIDTH and cheap:
                nodes[-1], entries[-1] = (g0, c1, below), entries[-1] + count
                continue
        nodes.append((c0, c1, below))
        entries.append(count)
    return nodes


def _scaled_columns(
    parts: list[tuple[np.ndarray, dict[int, int], np.ndarray]],
    n: int,
    roots: list[np.ndarray],
    row_scale: np.ndarray,
) -> np.ndarray | sp.spmatrix:
    """``diag(row_scale) B~ blockdiag(roots)`` (n, 6K) from ``B~``'s blocks ``parts``
    (pose columns, epoch column k -> column of the block, block), summed where they meet;
    dense (filled in place, no triplets) when more than ``DENSE_FRACTION`` of it is
    written, else sparse."""
    n_cols = POSE_DIM * len(roots)
    written = sum(len(rows) * POSE_DIM * len(col_of) for rows, col_of, _ in parts)
    if written > DENSE_FRACTION * n * n_cols:  # BLAS on the dense form is faster
        out = np.zeros((n, n_cols))
        for rows, col_of, block in parts:
            for k, c in col_of.items():
                out[rows, POSE_DIM * k : POSE_DIM * (k + 1)] += block[:, c : c + POSE_DIM]
        out *= row_scale[:, None]
        for k, root in enumerate(roots):
            cols = slice(POSE_DIM * k, POSE_DIM * (k + 1))
            out[:, cols] = out[:, cols] @ root
        return out
    if not parts:
        return sp.csr_matrix((n, n_cols))
    triplets: tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]] = ([], [], [])
    for rows, col_of, block in parts:
        for k, c in col_of.items():
            r, q = np.meshgrid(rows, POSE_DIM * k + np.arange(POSE_DIM), indexing="ij")
            for store, values in zip(triplets, (r, q, block[:, c : c + POSE_DIM]), strict=True):
                store.append(values.ravel())
    r, q, v = (np.concatenate(t) for t in triplets)
    Bt = sp.csr_matrix((v, (r, q)), shape=(n, n_cols))
    return sp.diags(row_scale) @ Bt @ sp.block_diag(roots, format="csr")


def _pose_blocks(
    sigma: np.ndarray, Bs: np.ndarray | sp.csr_matrix
) -> tuple[np.ndarray, np.ndarray]:
    """(E, 6, 6) twice: the diagonal blocks of the scaled ``sigma`` (n, n) and of
    ``(sigma Bs)(sigma Bs)^T`` (``Bs`` (n, 6K)), a chunk of rows at a time."""
    n, E = len(sigma), len(sigma) // POSE_DIM
    fitted = np.empty((E, POSE_DIM, POSE_DIM))
    extra = np.empty((E, POSE_DIM, POSE_DIM))
    for start in range(0, n, CHUNK_ROWS):
        stop = min(start + CHUNK_ROWS, n)
        block = sigma[start:stop]  # (r, n), the scaled Sigma's rows
        T = np.asarray(Bs.T @ block.T).T  # (r, 6K): scaled rows of Sigma B~ L
        T3 = T.reshape((stop - start) // POSE_DIM, POSE_DIM, -1)
        extra[start // POSE_DIM : stop // POSE_DIM] = T3 @ T3.transpose(0, 2, 1)
        diag = block.reshape(-1, POSE_DIM, E, POSE_DIM)
        idx = np.arange(start // POSE_DIM, stop // POSE_DIM)
        fitted[idx] = diag[np.arange(len(idx)), :, idx, :]
    return fitted, extra


def _scaled_inverse(S: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict[int, list[int]]]:
    """The inverse of the Jacobi-scaled poses' information ``S`` (n, n; overwritten), full,
    the scales ``d`` (n,) (``S^-1 = D^-1 Sigma_s D^-1``) and the poses' undetermined
    axes: as :func:`.marginals.determined_pose_marginals`, ``S + N N^T`` inverted where
    ``S`` has a null space ``N`` (the same covariance for every determined combination).

    Raises:
        numpy.linalg.LinAlgError: not positive definite on its determined directions.
    """
    n = len(S)
    d = np.sqrt(np.diag(S))
    d[d == 0.0] = 1.0
    for start in range(0, n, CHUNK_ROWS):  # S /= outer(d, d), without an (n, n) temporary
        S[start : start + CHUNK_ROWS] /= np.outer(d[start : start + CHUNK_ROWS], d)
    undetermined: dict[int, list[int]] = {}
    chol, info = lapack.dpotrf(S, lower=False)
    if info != 0:  # as determined_pose_marginals: S + N N^T on the null space N
        tol = UNDETERMINED_RTOL * float(np.max(np.diag(S)))
        U, piv, rank, _ = lapack.dpstrf(S, tol=tol, lower=False)
        perm = piv - 1
        U11, U12 = np.triu(U[:rank, :rank]), U[:rank, rank:]
        null = np.zeros((n, n - rank))
        null[perm[:rank]] = -solve_triangular(U11, U12)
        null[perm[rank:]] = np.eye(n - rank)
        N, _ = np.linalg.qr(null)
        for axis in np.flatnonzero((N**2).sum(axis=1) > 1e-9):
            undetermined.setdefault(int(axis) // POSE_DIM, []).append(int(axis) % POSE_DIM)
        chol, info = lapack.dpotrf(S + N @ N.T, lower=False)
        if info != 0:
            raise np.linalg.LinAlgError(f"pose information not positive definite ({info})")
    sigma, info = lapack.dpotri(chol, lower=False, overwrite_c=True)
    if info != 0:
        raise np.linalg.LinAlgError(f"pose information not invertible ({info})")
    _mirror_upper(sigma)  # the scaled Sigma, full
    return sigma, d, undetermined


def _mirror_upper(a: np.ndarray) -> None:
    """Copy the upper triangle of the square ``a`` onto its lower one, in place, a block
    of columns at a time (no (n, n) temporaries)."""
    n = len(a)
    for start in range(0, n, CHUNK_ROWS):
        stop = min(start + CHUNK_ROWS, n)
        block = a[start:stop, start:stop]
        block[...] = np.triu(block) + np.triu(block, 1).T
        a[stop:, start:stop] = a[start:stop, stop:].T


def _psd_root(q: np.ndarray) -> np.ndarray:
    """(6, 6) ``L`` with ``L L^T = q`` for a positive semi-definite ``q``."""
    w, V = np.linalg.eigh(0.5 * (q + q.T))
    return V * np.sqrt(np.maximum(w, 0.0))


def _eliminate(
    linear: gtsam.GaussianFactorGraph,
    members: list[int],
    pose_index: dict[int, int],
    dims: Mapping[int, int],
    error_maps: Mapping[int, tuple[int, np.ndarray]],
    S: np.ndarray,
    add_block,  # noqa: ANN001  (the closure of sandwich_pose_covariances)
) -> None:
    """One landmark group's factors (indices ``members`` of ``linear``) into the poses'
    information ``S`` and into ``B~``, the landmark variables eliminated; their
    undetermined directions (Jacobi-scaled eigenvalues below ``UNDETERMINED_RTOL``) left
    out, as :func:`.marginals._reduce_determined` (no information on the poses)."""
    factors = [linear.at(i) for i in members]
    local, m, poses, size = local_layout(factors, pose_index, dims)
    epochs = sorted({error_maps[i][0] for i in members if i in error_maps})
    col_of = {k: POSE_DIM * j for j, k in enumerate(epochs)}
    H = np.zeros((size, size))
    B = np.zeros((size, POSE_DIM * len(epochs)))
    for i, factor in zip(members, factors, strict=True):
        idx = np.concatenate(
            [local[k] + np.arange(POSE_DIM if k in pose_index else dims[k]) for k in factor.keys()]
        )
        A = factor.jacobian()[0]
        H[np.ix_(idx, idx)] += A.T @ A
        if i in error_maps:
            k, g = error_maps[i]
            B[idx, col_of[k] : col_of[k] + POSE_DIM] += A.T @ g
    H_ll, H_lp, H_pp = H[:m, :m], H[:m, m:], H[m:, m:]
    dl = np.sqrt(np.diag(H_ll))
    dl[dl == 0.0] = 1.0
    w, V = np.linalg.eigh(H_ll / np.outer(dl, dl))
    keep = w > UNDETERMINED_RTOL * max(float(w[-1]), 1.0)
    W = V[:, keep] / np.sqrt(w[keep])  # H_ll^+ = D^-1 W W^T D^-1
    Cp = W.T @ (H_lp / dl[:, None])
    pose_cols = pose_columns(poses, pose_index)
    reduced = Cp.T @ Cp
    np.subtract(H_pp, reduced, out=reduced)  # H_pp - Cp^T Cp, one (P, P) temporary
    first = int(pose_cols[0])
    if np.array_equal(pose_cols, np.arange(first, first + len(pose_cols))):  # in place
        S[first : first + len(pose_cols), first : first + len(pose_cols)] += reduced
    else:
        S[np.ix_(pose_cols, pose_cols)] += reduced
    if epochs:
        Cb = W.T @ (B[:m] / dl[:, None])
        add_block(pose_cols, col_of, B[m:] - Cp.T @ Cb)


def sandwich_covariances(
    graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    n_epochs: int,
    planes: Mapping[int, tuple[int, Plane]],
    motion_change: np.ndarray,
    relative_to_first: bool = True,
    prior_sigma: float = 1e-4,
) -> tuple[SandwichMarginals, str | None]:
    """(E, 6, 6) sandwich covariances of ``X(0..E-1)`` at ``values`` and a note naming
    undetermined pose axes (None when none).

    Args:
        graph: the covariance graph (:func:`.batch.covariance_graph`).
        values: the estimate.
        n_epochs: E.
        planes: index of a plane factor in ``graph`` -> (its epoch, its oriented measured
            plane) (``GraphUpdate.planes``, re-indexed to ``graph``).
        motion_change: (E, 6, 6) each epoch's ``Q_k``
            (:meth:`.DeskewNoise.plane_motion_change`).
        relative_to_first, prior_sigma: conditioned on the first pose as
            :func:`.marginals.pose_covariances`.
    """
    linear = graph.linearize(values)
    if relative_to_first:
        stiff = FIRST_POSE_TIGHTENING / prior_sigma
        linear.add(X(0), stiff * np.eye(6), np.zeros(6), gtsam.noiseModel.Unit.Create(6))
    zero = values.zeroVectors()
    dims = {key: zero.at(key).size for key in values.keys()}
    maps: dict[int, tuple[int, np.ndarray]] = {}
    for i, (epoch, plane) in planes.items():
        g = plane_error_map(graph.at(i), plane)
        if g is not None and np.any(motion_change[epoch]):
            maps[i] = (epoch, g)
    keys = [X(k) for k in range(n_epochs)]
    out = sandwich_pose_covariances(linear, keys, dims, maps, motion_change)
    poses = sorted(out.undetermined)
    note = None
    if poses:
        epochs = ", ".join(f"{k} (axes {out.undetermined[k]})" for k in poses)
        note = "undetermined pose axes, covariance NaN there: epochs " + epochs
    return out, note


def covariance_graph_index(
    graph: gtsam.NonlinearFactorGraph, cov_graph: gtsam.NonlinearFactorGraph
) -> dict[int, int]:
    """Index in ``graph`` -> index in its :func:`.batch.covariance_graph` ``cov_graph`` (which
    leaves out removed factors, unless it is ``graph`` itself)."""
    if cov_graph is graph:
        return {i: i for i in range(graph.size())}
    kept = [i for i in range(graph.size()) if graph.at(i) is not None]
    return {i: j for j, i in enumerate(kept)}


def deskew_motion_change(
    relative_poses: Sequence[RelativePose], n_epochs: int, half_window: int = 2
) -> np.ndarray:
    """(E, 6, 6) each epoch's covariance of its change of motion over its span
    (:meth:`.DeskewNoise.plane_motion_change`, from the run's own delta = 1 steps; zero for
    an epoch taken at one instant)."""
    model = DeskewNoise(half_window=half_window, plane_jacobian=True)
    for rel in relative_poses:
        model.add(rel)
    out = [model.plane_motion_change(k) for k in range(n_epochs)]
    return np.stack([np.zeros((6, 6)) if q is None else q for q in out])


def batch_sandwich(
    cfg: SmoothingConfig,
    graph: gtsam.NonlinearFactorGraph,
    cov_graph: gtsam.NonlinearFactorGraph,
    planes: Mapping[int, tuple[int, Plane]],
    Q: np.ndarray,
    estimate: gtsam.Values,
) -> tuple[np.ndarray, str | None]:
    """``smoothing.covariance_model`` "sandwich" of the batch (``graph``, its covariance
    graph ``cov_graph``, :func:`.batch.covariance_graph`): (E, 6, 6) and a note
    (:func:`sandwich_covariances`; ``Q`` (E, 6, 6) the epochs' changes of
    motion, :func:`deskew_motion_change`)."""
    index = covariance_graph_index(graph, cov_graph)
    mapped = {index[i]: obs for i, obs in planes.items() if i in index}
    out, note = sandwich_covariances(
        cov_graph, estimate, len(Q), mapped, Q, cfg.covariances_relative_to_first,
        cfg.prior_sigma,
    )  # fmt: skip
    return out.covariances, note
