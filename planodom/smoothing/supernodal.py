"""Supernodal storage of a symmetric matrix on its factor's pattern, and that pattern, for
the selected inversion of :mod:`.sparse_sandwich`."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numba
import numpy as np
import scipy.sparse as sp


@dataclass
class Panels:
    """The supernodes' panels of a symmetric (N, N) matrix, in the elimination order:
    node ``k``'s columns [c0, c1) (width ``w``) and rows ``c0 .. c1-1`` then its rows
    below, a dense (w + |below|, w) block, row-major, of the flat ``values`` from
    ``offset[k]``. Only the lower triangle (row >= column) is addressed: the entries
    of the factor's (padded) pattern, about ``nnz(L)``, instead of ``N x N``.

    Attributes:
        nodes: each node's (c0, c1, rows below).
        offset: (nodes + 1,) each panel's start in the flat values.
        node_of: (N,) the node of each column.
        keys: ``node * N + row`` of each node's rows in order (sorted).
        row_start: (nodes + 1,) each node's first row among ``keys``.
        first: (nodes + 1,) each node's first column, then N.
    """

    nodes: list[tuple[int, int, np.ndarray]]
    offset: np.ndarray
    node_of: np.ndarray
    keys: np.ndarray
    row_start: np.ndarray
    first: np.ndarray

    @classmethod
    def of(cls, nodes: list[tuple[int, int, np.ndarray]], N: int) -> Panels:
        widths = np.array([c1 - c0 for c0, c1, _ in nodes], dtype=np.int64)
        heights = widths + np.array([len(b) for _, _, b in nodes], dtype=np.int64)
        offset = np.concatenate([[0], np.cumsum(widths * heights)])
        node_of = np.repeat(np.arange(len(nodes)), widths)
        keys = np.concatenate(
            [k * N + np.concatenate([np.arange(c0, c1), b]) for k, (c0, c1, b) in enumerate(nodes)]
        ).astype(np.int64)
        row_start = np.concatenate([[0], np.cumsum(heights)])
        first = np.array([c0 for c0, _, _ in nodes] + [N], dtype=np.int64)
        return cls(nodes, offset, node_of, keys, row_start, first)

    def panel(self, values: np.ndarray, k: int) -> np.ndarray:
        """Node ``k``'s panel of ``values``, a (w + |below|, w) view."""
        c0, c1, below = self.nodes[k]
        return values[self.offset[k] : self.offset[k + 1]].reshape(c1 - c0 + len(below), c1 - c0)

    def index(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Flat positions of the entries (``rows``, ``cols``) (elimination order, any
        shapes that broadcast; each pair read in the lower triangle).

        Raises:
            ValueError: an entry outside the pattern.
        """
        N = len(self.node_of)
        lo, hi = np.maximum(rows, cols), np.minimum(rows, cols)
        node = self.node_of[hi]
        want = node * N + lo
        slot = np.minimum(np.searchsorted(self.keys, want), len(self.keys) - 1)
        if not np.array_equal(self.keys[slot], want):
            raise ValueError("an entry outside the factor's pattern")
        width = self.first[node + 1] - self.first[node]
        at = self.offset[node] + (slot - self.row_start[node]) * width
        return at + (hi - self.first[node])

    def lower(self, below: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The pairs (i >= j) of ``below``'s entries (their local indices, (m(m+1)/2,)
        twice) and their flat positions."""
        ti, tj = _tril(len(below))
        return ti, tj, self.index(below[ti], below[tj])


@functools.lru_cache(maxsize=256)
def _tril(m: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.tril_indices(m)``, kept (read only): the same widths recur node after node."""
    ti, tj = np.tril_indices(m)
    ti.flags.writeable = tj.flags.writeable = False
    return ti, tj


def m_matrix(pattern: sp.csc_matrix) -> sp.csc_matrix:
    """A matrix of ``pattern``'s structure (N, N; its stored entries, explicit zeros too,
    so the fill-reducing ordering is the structure's) whose LU factor has the symbolic
    Cholesky pattern: -1 off the diagonal, each row's count plus one on it (a strictly
    diagonally dominant M-matrix: every Schur update adds terms of one sign, so no fill
    entry cancels to zero). ``|K| + |M| + I`` (SANDFIX's) is not one: on the 2 000-epoch
    lap 45 of its factor's 1.25 M entries cancelled, and the supernodes missed them.
    Its factor's pattern is still not taken: fill entries underflow to zero on long
    chains (LAP14: 72 on lap 366 at 6 mm); only the ordering is, the pattern comes from
    :func:`cholesky_pattern`."""
    S = pattern.tocsc(copy=True)
    S.data[:] = -1.0
    S.setdiag(0.0)
    count = -np.asarray(S.sum(axis=1)).ravel()
    S.setdiag(count + 1.0)
    return S


def cholesky_pattern(pattern: sp.spmatrix, perm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The symbolic Cholesky factor's pattern of the symmetric ``pattern`` (N, N; its
    stored entries, explicit zeros too) in the elimination order ``perm`` (variable i at
    position ``perm[i]``): CSC ``(indices, indptr)``, each column's rows sorted, the
    diagonal first. From the structure alone (each column: its own lower entries and its
    elimination-tree children's columns less their diagonals), so no entry can go
    missing: a numeric factor's pattern drops the fill entries whose values reach exactly
    zero, and even :func:`m_matrix`'s, which cannot cancel, underflows on long chains
    (LAP14: lap 366 at 6 mm)."""
    N = pattern.shape[0]
    coo = sp.coo_matrix(pattern)
    r, c = perm[coo.row], perm[coo.col]
    lo, hi = np.maximum(r, c), np.minimum(r, c)
    lower = sp.csc_matrix(
        (
            np.ones(len(lo) + N),
            (np.concatenate([lo, np.arange(N)]), np.concatenate([hi, np.arange(N)])),
        ),
        shape=(N, N),
    )  # duplicates summed: one entry per (row, column)
    lower.sort_indices()
    return _symbolic_columns(lower.indices.astype(np.int64), lower.indptr.astype(np.int64), N)


@numba.njit(cache=True)
def _symbolic_columns(
    ind: np.ndarray, ptr: np.ndarray, N: int
) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """:func:`cholesky_pattern`'s columns from the lower triangle's sorted CSC (``ind``,
    ``ptr``; the diagonal stored): column j is its own entries and its elimination-tree
    children's columns less their diagonals, sorted; its parent is its first row below
    the diagonal. Compiled (numba) because it is a loop over the N columns, each merging
    a few short index lists: in Python it was 0.3 s at N = 9 255 (LAP14); no scipy
    routine returns a symbolic Cholesky pattern. Children are kept as linked lists
    (``head``/``nxt``), the union by a marker per row."""
    head = np.full(N, -1, np.int64)  # each column's first child, then the next sibling
    nxt = np.full(N, -1, np.int64)
    mark = np.full(N, -1, np.int64)
    indptr = np.zeros(N + 1, np.int64)
    out = np.empty(max(2 * len(ind), 16), np.int64)
    for j in range(N):
        start = indptr[j]
        n = 0
        for q in range(ptr[j], ptr[j + 1]):
            out, n = _taken(out, start, n, ind[q], mark, j)
        child = head[j]
        while child != -1:
            for q in range(indptr[child] + 1, indptr[child + 1]):
                out, n = _taken(out, start, n, out[q], mark, j)
            child = nxt[child]
        out[start : start + n].sort()
        indptr[j + 1] = start + n
        if n > 1:
            parent = out[start + 1]
            nxt[j] = head[parent]
            head[parent] = j
    return out[: indptr[N]].astype(np.int32), indptr


@numba.njit(cache=True)
def _taken(
    out: np.ndarray, start: int, n: int, r: int, mark: np.ndarray, j: int
) -> tuple[np.ndarray, int]:  # pragma: no cover - compiled
    """Row ``r`` appended to column ``j``'s rows ``out[start : start + n]`` unless
    ``mark`` holds it already (``out`` grown when full); the array and the new count."""
    if mark[r] != j:
        mark[r] = j
        if start + n >= len(out):
            out = _grown(out)
        out[start + n] = r
        n += 1
    return out, n


@numba.njit(cache=True)
def _grown(a: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """``a`` copied into an array twice as long."""
    b = np.empty(2 * len(a), a.dtype)
    b[: len(a)] = a
    return b
