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

By default (``SELECTED_INVERSION``) without forming ``Sigma``: the pose blocks of
``Sigma`` and of ``Sigma B~ Q B~^T Sigma = -d/de (P + e B~ Q B~^T)^-1`` are what a sparse
selected inversion (Takahashi's recursion over supernodes) and its exact derivative give
(:func:`.sparse_sandwich.sparse_pose_covariances`, in extended precision); the dense path
(:func:`_dense_pose_covariances`) remains for poses with undetermined axes and where
numpy has no extended precision.

Not modelled by default: the deskewing error of the relative-pose and loop-candidate
factors (they enter only where planes are not plane factors, ``smoothing.between_factors``;
the loop factors' older epoch's with ``sandwich_loop_sources`` "deskew", :mod:`.loop_deskew`;
both epochs' of every such factor with ``sandwich_relative_ends`` "both",
:mod:`.relative_deskew`) and of factors the robust kernel down-weights at the estimate
(outliers of :func:`.batch_covariances.covariance_graph`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import gtsam
import numpy as np
import scipy.sparse as sp
from scipy.linalg import lapack, solve_triangular

from planodom.config import SmoothingConfig
from planodom.geometry import Plane
from planodom.odometry.relative import RelativePose
from planodom.smoothing import sparse_sandwich
from planodom.smoothing.deskew_noise import DeskewNoise
from planodom.smoothing.error_maps import ErrorMaps, map_terms, merged, plane_error_map
from planodom.smoothing.graph import X
from planodom.smoothing.loop_planes import plane_columns
from planodom.smoothing.loop_records import LoopFactor
from planodom.smoothing.loop_sources import loop_error_maps
from planodom.smoothing.marginals import (
    FIRST_POSE_TIGHTENING,
    POSE_DIM,
    UNDETERMINED_RTOL,
    local_layout,
    pose_columns,
    split_factors,
)
from planodom.smoothing.plane_share import less_own, own_columns
from planodom.smoothing.relative_deskew import relative_error_maps
from planodom.smoothing.sparse_sandwich import NotDefinite, psd_root, sparse_pose_covariances

#: Pose rows per chunk of ``Sigma B~`` (memory: chunk times the poses' dimension).
CHUNK_ROWS = 1200

#: ``B~`` is multiplied in dense form (BLAS) when more than this share of it is non-zero
#: (a ground plane seen by every epoch fills it; scipy's sparse product is single-threaded
#: and several times slower per non-zero than a dense one).
DENSE_FRACTION = 0.1


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
    error_maps: ErrorMaps,
    motion_change: np.ndarray,
) -> SandwichMarginals:
    """The poses' sandwich covariances (module docstring) of a linearised graph.

    By the dense path (:func:`_dense_pose_covariances`); with ``SELECTED_INVERSION`` (and
    an ``EXTENDED`` precision) by a sparse selected inversion
    (:func:`.sparse_sandwich.sparse_pose_covariances`), the dense path taking over where
    that meets a pivot at the undetermined level.

    Args:
        linear: the linearised (whitened) graph at the estimate.
        pose_keys: the E pose keys, in output order.
        dims: tangent dimension of every key of ``linear``.
        error_maps: index of a factor in ``linear`` -> (its epoch column k, (m, 6) change
            of its whitened error with ``dxi_k``, m its dimension), or several such terms
            (:mod:`.error_maps`).
        motion_change: (K, 6, 6) ``Q_k``, the covariance of ``dxi_k`` per epoch column.

    Raises:
        numpy.linalg.LinAlgError: the poses' information is not positive definite even on
            its determined directions.
    """
    if not sparse_sandwich.SELECTED_INVERSION or sparse_sandwich.EXTENDED is None:
        return _dense_pose_covariances(linear, pose_keys, dims, error_maps, motion_change)
    try:
        covariances, fitted = sparse_pose_covariances(
            linear, pose_keys, dims, error_maps, motion_change
        )
    except NotDefinite:
        return _dense_pose_covariances(linear, pose_keys, dims, error_maps, motion_change)
    return SandwichMarginals(covariances, fitted, {}, len(error_maps))


def _dense_pose_covariances(
    linear: gtsam.GaussianFactorGraph,
    pose_keys: Sequence[int],
    dims: Mapping[int, int],
    error_maps: ErrorMaps,
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
        for k, g in map_terms(error_maps, i):
            add_block(pcols, {k: 0}, A.T @ g)
    for members in by_group.values():
        _eliminate(linear, members, pose_index, dims, error_maps, S, add_block)
    sigma, d, undetermined = _scaled_inverse(S)
    del S
    # Q_k = L_k L_k^T folded into B~'s columns: the extra term's block i is then
    # (Sigma B~ L)_i (Sigma B~ L)_i^T, one batched product per chunk of poses.
    roots = [psd_root(q) for q in np.asarray(motion_change, dtype=float)]
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


def _eliminate(
    linear: gtsam.GaussianFactorGraph,
    members: list[int],
    pose_index: dict[int, int],
    dims: Mapping[int, int],
    error_maps: ErrorMaps,
    S: np.ndarray,
    add_block,  # noqa: ANN001  (the closure of sandwich_pose_covariances)
) -> None:
    """One landmark group's factors (indices ``members`` of ``linear``) into the poses'
    information ``S`` and into ``B~``, the landmark variables eliminated; their
    undetermined directions (Jacobi-scaled eigenvalues below ``UNDETERMINED_RTOL``) left
    out, as :func:`.marginals._reduce_determined` (no information on the poses)."""
    factors = [linear.at(i) for i in members]
    local, m, poses, size = local_layout(factors, pose_index, dims)
    epochs = sorted({k for i in members for k, _ in map_terms(error_maps, i)})
    col_of = {k: POSE_DIM * j for j, k in enumerate(epochs)}
    H = np.zeros((size, size))
    B = np.zeros((size, POSE_DIM * len(epochs)))
    for i, factor in zip(members, factors, strict=True):
        idx = np.concatenate(
            [local[k] + np.arange(POSE_DIM if k in pose_index else dims[k]) for k in factor.keys()]
        )
        A = factor.jacobian()[0]
        H[np.ix_(idx, idx)] += A.T @ A
        for k, g in map_terms(error_maps, i):
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
    extra: tuple[ErrorMaps, np.ndarray] | None = None,
    own: bool = False,
) -> tuple[SandwichMarginals, str | None]:
    """(E, 6, 6) sandwich covariances of ``X(0..E-1)`` at ``values`` and a note naming
    undetermined pose axes (None when none).

    Args:
        graph: the covariance graph (:func:`.batch_covariances.covariance_graph`).
        values: the estimate.
        n_epochs: E.
        planes: index of a plane factor in ``graph`` -> (its epoch, its oriented measured
            plane) (``GraphUpdate.planes``, re-indexed to ``graph``).
        motion_change: (E, 6, 6) each epoch's ``Q_k``
            (:meth:`.DeskewNoise.plane_motion_change`).
        relative_to_first, prior_sigma: conditioned on the first pose as
            :func:`.marginals.pose_covariances`.
        extra: more error maps (into the epochs' columns or columns from E on) and the
            (K, 6, 6) covariances of the columns from E on.
        own: the plane factors' noise models hold their own share of their epoch's
            deskewing error (``sandwich_plane_share`` "own"): it is left out of ``S``
            (:mod:`.plane_share`).
    """
    linear = graph.linearize(values)
    if relative_to_first:
        stiff = FIRST_POSE_TIGHTENING / prior_sigma
        linear.add(X(0), stiff * np.eye(6), np.zeros(6), gtsam.noiseModel.Unit.Create(6))
    zero = values.zeroVectors()
    dims = {key: zero.at(key).size for key in values.keys()}
    maps: ErrorMaps = {}
    for i, (epoch, plane) in planes.items():
        g = plane_error_map(graph.at(i), plane)
        if g is not None and np.any(motion_change[epoch]):
            maps[i] = (epoch, g)  # type: ignore[index]  # built here, a dict
    plane_maps = dict(maps)
    if extra is not None and extra[0]:
        maps, motion_change = merged(maps, extra[0]), np.concatenate([motion_change, extra[1]])
    keys = [X(k) for k in range(n_epochs)]
    out = sandwich_pose_covariances(linear, keys, dims, maps, motion_change)
    if own and plane_maps:
        own_maps, q_own = own_columns(plane_maps, motion_change)
        out = less_own(out, sandwich_pose_covariances(linear, keys, dims, own_maps, q_own))
    poses = sorted(out.undetermined)
    note = None
    if poses:
        epochs = ", ".join(f"{k} (axes {out.undetermined[k]})" for k in poses)
        note = "undetermined pose axes, covariance NaN there: epochs " + epochs
    return out, note


def covariance_graph_index(
    graph: gtsam.NonlinearFactorGraph, cov_graph: gtsam.NonlinearFactorGraph
) -> dict[int, int]:
    """Index in ``graph`` -> index in its :func:`.batch_covariances.covariance_graph`
    ``cov_graph`` (which leaves out removed factors, unless it is ``graph`` itself)."""
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
    loops: tuple[Sequence[LoopFactor], Mapping[int, Sequence[Plane]]] = ((), {}),
    relatives: tuple[Sequence[RelativePose], Sequence[int]] = ((), ()),
) -> tuple[np.ndarray, str | None]:
    """``smoothing.covariance_model`` "sandwich" of the batch (``graph``; ``cov_graph`` its
    :func:`.batch_covariances.covariance_graph`): (E, 6, 6) and a note. ``Q`` (E, 6, 6): the
    epochs' changes of motion; ``loops``: the loop factors and planes per epoch
    (``sandwich_loop_sources``: :mod:`.loop_sources`, :mod:`.loop_planes`); ``relatives``: the
    relative poses and the fallbacks (``sandwich_relative_ends``, :mod:`.relative_deskew`)."""
    index = covariance_graph_index(graph, cov_graph)
    mapped = {index[i]: obs for i, obs in planes.items() if i in index}
    mode, dm, ends = cfg.sandwich_loop_sources, cfg.delta_max, cfg.sandwich_relative_ends
    mode = "independent" if ends != "none" and mode == "deskew" else mode  # "both" has it
    extra: tuple[ErrorMaps, np.ndarray] | None
    extra = loop_error_maps(mode, cov_graph, estimate, Q, dm, index, loops)
    if ends != "none":  # "loops": the loop factors' ends alone (no relative pose is a source)
        skip = {index[i] for i in relatives[1] if i in index}
        steps = relatives[0] if ends == "both" else ()
        both = relative_error_maps(cov_graph, estimate, Q, dm, index, loops, steps, skip)
        extra = (both, np.zeros((0, 6, 6))) if extra is None else (merged(extra[0], both), extra[1])
    extra, own = plane_columns(mode, extra, cov_graph, estimate, loops, index, mapped, len(Q))
    out, note = sandwich_covariances(
        cov_graph, estimate, len(Q), mapped, Q, cfg.covariances_relative_to_first,
        cfg.prior_sigma, extra, cfg.sandwich_plane_share == "own",
    )  # fmt: skip
    if own is not None:  # "planes": each factor's own variance kept (loop_planes)
        q0, rel, sigma = 0 * Q, cfg.covariances_relative_to_first, cfg.prior_sigma
        out = less_own(
            out, sandwich_covariances(cov_graph, estimate, len(Q), {}, q0, rel, sigma, own)[0]
        )
    return out.covariances, note
