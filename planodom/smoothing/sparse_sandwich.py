"""The sandwich covariances' poses blocks by a sparse selected inversion (on by default:
``SELECTED_INVERSION``; :func:`.sandwich.sandwich_pose_covariances` uses it when on).

The pose blocks of ``Sigma`` and of ``Sigma B~ Q B~^T Sigma = -d/de (P + e B~ Q B~^T)^-1``
(:mod:`.sandwich`'s notation) from Takahashi's recursion over supernodes carried with its
exact derivative, on a sparse system that keeps the landmark groups' determined
directions as variables (:func:`sparse_pose_covariances`), in extended precision
(``EXTENDED``; :func:`_selected_inverse` says why).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import gtsam
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from planodom.smoothing.error_maps import ErrorMaps, map_terms
from planodom.smoothing.marginals import POSE_DIM, UNDETERMINED_RTOL, split_factors
from planodom.smoothing.supernodal import Panels, cholesky_pattern, m_matrix


class NotDefinite(Exception):
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

#: On (the sandwich option's path; the dense one where it meets an undetermined pivot or
#: without ``EXTENDED``): equal to the dense path to round-off of the standard deviations
#: on the 2D-rig laps of docs/RESULTS.md (SANDFIX) and several times faster. Before, it
#: was off: 1e-3 (world 2 at 6 mm) from ``R R^T`` rounded to double and 2-4e-4 in the
#: fitted blocks from an explicit pivot inverse (:func:`_selected_inverse`).
SELECTED_INVERSION = True

#: The selected inversion's arithmetic (:func:`_selected_inverse`: the extra term is a
#: cancellation that double precision leaves 1e-3 of the standard deviations off on the
#: worse conditioned laps): numpy's long double where it is the x87 80-bit format (64-bit
#: significand; x86-64 Linux and macOS), else None and the dense path is used (where long
#: double is double, or IEEE quad in software, several times slower).
EXTENDED: type[np.floating] | None = np.longdouble if np.finfo(np.longdouble).nmant == 63 else None

#: Diagnostic: the selected inversion on the poses' sparse Schur complement instead of
#: the system with the landmarks' determined directions (the same differences).
POSE_SPACE = False


def sparse_pose_covariances(
    linear: gtsam.GaussianFactorGraph,
    pose_keys: Sequence[int],
    dims: Mapping[int, int],
    error_maps: ErrorMaps,
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
        NotDefinite: a pivot of the Jacobi-scaled ``K`` is not above
            ``UNDETERMINED_RTOL`` of its largest diagonal entry (an undetermined pose axis),
            or a pose's variance comes out not positive (a system near singular).
    """
    E = len(pose_keys)
    n = POSE_DIM * E
    H, B, groups = _whitened_system(linear, pose_keys, dims, error_maps, len(motion_change))
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
    roots = [psd_root(q) for q in np.asarray(motion_change, dtype=float)]
    rhs = (rhs @ sp.block_diag(roots, format="csr")).tocsc() if roots else rhs.tocsc()
    ds = np.sqrt(K.diagonal())
    ds[ds == 0.0] = 1.0
    Dinv = sp.diags(1.0 / ds)
    Rs = Dinv @ rhs
    # each pose's 6 x 6 block wanted whole (some have structural zeros in K)
    blocks6 = sp.block_diag([np.ones((POSE_DIM, POSE_DIM))] * E, format="csc")
    wanted = sp.block_diag([blocks6, sp.csc_matrix((K.shape[0] - n, K.shape[0] - n))])
    Z = _selected_inverse(Dinv @ K @ Dinv, Rs, wanted)
    pos = np.arange(n).reshape(E, POSE_DIM)
    values, derivative = Z.entries(pos[:, :, None], pos[:, None, :])
    fitted, extra = values.astype(float), -derivative.astype(float)
    # Not rank-revealing: a system near singular (lap 366 at 6 mm: condition 7e15, its
    # smallest pivot 2e-12 passes) comes out with negative variances; the dense path's
    # pivoted Cholesky takes over there (LAP14).
    diagonal = np.diagonal(fitted, axis1=1, axis2=2), np.diagonal(fitted + extra, axis1=1, axis2=2)
    if not all(np.all(d > 0.0) for d in diagonal):
        raise NotDefinite
    scale = ds[:n].reshape(E, POSE_DIM)
    outer = scale[:, :, None] * scale[:, None, :]
    return (fitted + extra) / outer, fitted / outer


def _whitened_system(
    linear: gtsam.GaussianFactorGraph,
    pose_keys: Sequence[int],
    dims: Mapping[int, int],
    error_maps: ErrorMaps,
    K_count: int,
) -> tuple[sp.csr_matrix, sp.csr_matrix, list[tuple[int, int]]]:
    """``H = J^T J`` (N, N) and ``B = J^T G`` (N, 6 K_count) of the whitened Jacobian ``J``
    and the error maps ``G``, the poses first (6 each, ``pose_keys`` order), then each
    landmark group's variables; and each group's columns among the landmarks' [start,
    stop)."""
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
        for k, g in map_terms(error_maps, i):
            g_rows.append(np.repeat(r, POSE_DIM))
            g_cols.append(np.tile(POSE_DIM * k + np.arange(POSE_DIM), len(r)))
            g_vals.append(np.asarray(g, dtype=float).ravel())
        row += A.shape[0]
    N_all = n + m_all
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
    return (Jt @ J).tocsr(), (Jt @ G).tocsr(), groups


def _mm(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` by numpy's own loops, not BLAS: the selected inversion's blocks are small
    (tens to a few hundred rows), where OpenBLAS's threads cost more than the product
    and stall when the cores are busy (measured, world 14 at 2 cm: 6-15 s against 1.5 s
    with one BLAS thread); and they run in ``EXTENDED``, which BLAS does not have."""
    return np.einsum("ij,jk->ik", a, b)


@dataclass
class _Selected:
    """Entries of a symmetric matrix's inverse and of its derivative on the factor's
    pattern, as supernodal panels (:class:`Panels`; variable i at ``position[i]`` in
    the elimination order)."""

    values: np.ndarray
    derivative: np.ndarray
    panels: Panels
    position: np.ndarray

    def entries(self, rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The inverse's and the derivative's entries (variables ``rows``, ``cols``, any
        broadcasting shapes, on the pattern), in ``EXTENDED``."""
        at = self.panels.index(self.position[rows], self.position[cols])
        return self.values[at], self.derivative[at]


def _selected_inverse(K: sp.spmatrix, R: sp.spmatrix, wanted: sp.spmatrix) -> _Selected:
    """``K^-1`` on the pattern of ``K + R R^T + wanted``'s factor (``wanted``: a pattern
    of entries to be computed, e.g. whole diagonal blocks), and there the first-order
    change ``d/de (K + e M)^-1 = -K^-1 M K^-1`` with ``M = R R^T`` (``K`` (N, N) sparse
    positive definite, ``R`` (N, c) sparse), both by block elimination over supernodes,
    in ``EXTENDED`` precision (values returned in it), stored as the supernodes' panels
    (:class:`Panels`: about the factor's entries, not ``N x N``).

    Block Cholesky of ``K(e)`` (pivot blocks ``P_J = L_J L_J^T``, panel ``G = K_IJ
    L_J^-T``, ``K_II -= G G^T``) and Takahashi's selected inversion (``Z_IJ = -Z_II G
    L_J^-1``, ``Z_JJ = L_J^-T (I + G^T Z_II G) L_J^-1``, from the last block to the
    first) on the supernodes' patterns, each carried with its derivative in ``e``
    (forward-mode, exact: no finite step): the cost of the fitted marginals' selected
    inversion, about twice, instead of ``N`` solves.

    Why the panel and not ``F = K_IJ P_J^-1`` with an explicit ``P_J^-1``: the pivot
    blocks of the worse conditioned laps are themselves ill-conditioned, and the Schur
    update ``F K_JI`` through the explicit inverse put the fitted blocks 2-4e-4 of their
    standard deviations off on world 2 at 6 mm (one-column blocks were at round-off);
    ``G G^T`` is at round-off at every width (1.4e-7). Why ``EXTENDED``: ``R``'s columns
    lie in the range of the whitened Jacobian's transpose, so ``K^-1 R`` is of moderate
    size while ``K^-1`` is not (condition 6e9 on that lap): ``K^-1 M K^-1`` is a
    cancellation of terms ``|K^-1| |M| |K^-1|``, and ``M``'s rounding to double alone
    moves the extra term by 1.6e-4 of the standard deviations (1e-3 with the recursion's
    own rounding). ``M`` formed and the recursion run in extended precision: 2-4e-8 from an
    iteratively refined solve of ``K^-1 R`` (the dense path: 4e-7).

    Raises:
        NotDefinite: a pivot block is not positive definite, or a pivot of its Cholesky
            factor not above ``UNDETERMINED_RTOL`` of the largest diagonal entry.
    """
    N = K.shape[0]
    Rx = sp.csr_matrix(R, dtype=EXTENDED)
    M = (Rx @ Rx.T.tocsr()).tocsr()  # R R^T, rounded once in EXTENDED
    # (a copy: a float view of M shares its indices, which scipy may sort in place)
    pattern = (abs(K) + abs(sp.csr_matrix(M, dtype=float, copy=True)) + abs(wanted)).tocsc()
    lu = spla.splu(
        m_matrix(pattern), permc_spec="MMD_AT_PLUS_A",
        diag_pivot_thresh=0.0, options={"SymmetricMode": True, "Equil": False},
    )  # fmt: skip
    perm = lu.perm_c  # variable i is row perm[i] of the factor
    del lu  # its ordering only: its L drops fill entries that underflow to zero
    indices, indptr = cholesky_pattern(pattern, perm)
    del pattern
    panels = Panels.of(_supernodes(indices, indptr, N), N)
    del indices, indptr
    A, dA = _scattered(K, perm, panels), _scattered(M, perm, panels)
    del M, Rx
    top = float(np.max(K.diagonal(), initial=1.0))
    factors = _factor(A, dA, panels, top)
    _takahashi(A, dA, panels, factors)
    return _Selected(A, dA, panels, perm)


def _scattered(S: sp.spmatrix, perm: np.ndarray, panels: Panels) -> np.ndarray:
    """The lower triangle of the symmetric sparse ``S`` (N, N) in the elimination order
    (``S_ij`` at row ``perm[i]``, column ``perm[j]``) on ``panels``, flat, ``EXTENDED``."""
    coo = S.tocoo()
    r, c = perm[coo.row], perm[coo.col]
    keep = r >= c
    out = np.zeros(int(panels.offset[-1]), dtype=EXTENDED)
    out[panels.index(r[keep], c[keep])] = coo.data[keep]
    return out


_Factor = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]  # L_J^-1, its d, G, dG


def _factor(A: np.ndarray, dA: np.ndarray, panels: Panels, top: float) -> list[_Factor]:
    """:func:`_selected_inverse`'s block Cholesky over the nodes (columns [c0, c1), rows
    below) with its derivative, Schur complements left in the panels of ``A`` and ``dA``
    (in place; ``top``: the largest diagonal entry); each node's ``(L_J^-1, d L_J^-1,
    G, dG)``."""
    factors = []
    for k, (c0, c1, below) in enumerate(panels.nodes):
        w = c1 - c0
        PA, PdA = panels.panel(A, k), panels.panel(dA, k)
        chol = _cholesky(PA[:w])
        if not np.all(np.diag(chol) ** 2 > UNDETERMINED_RTOL * top):
            raise NotDefinite
        Li = _lower_inverse(chol)
        dP = np.tril(PdA[:w])
        dP += np.tril(dP, -1).T
        # d(L L^T) = dP: dL = L Phi, Phi the lower half of L^-1 dP L^-T (diagonal halved)
        Phi = np.tril(_mm(_mm(Li, dP), Li.T))
        Phi[np.diag_indices(w)] *= 0.5
        G = _mm(PA[w:], Li.T)  # K_IJ L^-T, (|I|, w)
        dG = _mm(PdA[w:], Li.T) - _mm(G, Phi.T)
        if len(below):
            ti, tj, at = panels.lower(below)
            A[at] -= _mm(G, G.T)[ti, tj]
            half = _mm(dG, G.T)
            dA[at] -= (half + half.T)[ti, tj]
        factors.append((Li, -_mm(Phi, Li), G, dG))
    return factors


def _takahashi(A: np.ndarray, dA: np.ndarray, panels: Panels, factors: list[_Factor]) -> None:
    """:func:`_selected_inverse`'s selected inversion with its derivative, from the last
    node to the first, written over the panels of ``A`` and ``dA``."""
    for k in reversed(range(len(panels.nodes))):
        c0, c1, below = panels.nodes[k]
        Li, dLi, G, dG = factors[k]
        w = c1 - c0
        PA, PdA = panels.panel(A, k), panels.panel(dA, k)
        inner = np.eye(w, dtype=A.dtype)  # I + G^T Z_II G
        d_inner = np.zeros_like(inner)
        if len(below):
            ti, tj, at = panels.lower(below)
            m = len(below)
            ZII, dZII = np.empty((m, m), dtype=A.dtype), np.empty((m, m), dtype=A.dtype)
            ZII[ti, tj] = ZII[tj, ti] = A[at]
            dZII[ti, tj] = dZII[tj, ti] = dA[at]
            both = _mm(ZII, np.hstack([G, dG]))  # Z_II G, Z_II dG
            U = both[:, :w]
            dU = _mm(dZII, G) + both[:, w:]
            PA[w:] = -_mm(U, Li)
            PdA[w:] = -_mm(dU, Li) - _mm(U, dLi)
            inner += _mm(G.T, U)
            d_inner = _mm(dG.T, U) + _mm(G.T, dU)
        right = _mm(inner, Li)
        ZJJ = _mm(Li.T, right)
        dZJJ = _mm(dLi.T, right) + _mm(Li.T, _mm(d_inner, Li) + _mm(inner, dLi))
        PA[:w] = 0.5 * (ZJJ + ZJJ.T)
        PdA[:w] = 0.5 * (dZJJ + dZJJ.T)


def _cholesky(P: np.ndarray) -> np.ndarray:
    """Lower Cholesky factor of the small ``P`` (w, w) in its own precision (LAPACK has
    no ``EXTENDED``), a column at a time.

    Raises:
        NotDefinite: ``P`` is not positive definite.
    """
    w = len(P)
    L = np.zeros_like(P)
    for j in range(w):
        pivot = P[j, j] - _mm(L[j : j + 1, :j], L[j, :j, None])[0, 0]
        if not pivot > 0.0:
            raise NotDefinite
        L[j, j] = np.sqrt(pivot)
        L[j + 1 :, j] = (P[j + 1 :, j] - _mm(L[j + 1 :, :j], L[j, :j, None])[:, 0]) / L[j, j]
    return L


def _lower_inverse(L: np.ndarray) -> np.ndarray:
    """The inverse of the small lower-triangular ``L`` (w, w) in its own precision, a
    row at a time (forward substitution on the identity)."""
    w = len(L)
    X = np.zeros_like(L)
    for i in range(w):
        X[i, : i + 1] = -_mm(L[i : i + 1, :i], X[:i, : i + 1])[0]
        X[i, i] += 1.0
        X[i, : i + 1] /= L[i, i]
    return X


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


def psd_root(q: np.ndarray) -> np.ndarray:
    """(6, 6) ``L`` with ``L L^T = q`` for a positive semi-definite ``q``."""
    w, V = np.linalg.eigh(0.5 * (q + q.T))
    return V * np.sqrt(np.maximum(w, 0.0))
