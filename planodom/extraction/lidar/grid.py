"""The range image of a ringed 3D scan: one row per ring, one column per firing.

A spinning lidar's points form a grid: one row per ring (rows in ring-id order, which a
lidar driver's ``ring`` field follows: lowest beam first, or highest) and one column per
firing. The column of a point is taken from its time within its ring,
``round((t - t_min) / dt)`` with ``dt`` the median time step between consecutive points
of a ring (dropped no-return beams leave empty pixels); without usable times (all equal: a
snapshot) there are no columns and the caller uses RANSAC. Only what a recorded cloud with
rings has is used: ``ring``, the points' order within a ring, ``t``.

Here: the grid indices (:func:`grid_indices`), the grid of points (:func:`fill_grid`),
pieces near each other in the grid (:func:`near_pairs`) and the assignment of every point
to a plane of its pixel's neighbourhood (:func:`assign_points`), compiled with numba (one
pass over ~3 * 10^4 pixels or points each, where numpy needs full-grid temporaries).
"""

from __future__ import annotations

import numba
import numpy as np

from planodom.extraction.memo import identity_memo, read_only
from planodom.median import median


def ring_rows(ring: np.ndarray) -> tuple[np.ndarray, int]:
    """Row (N,) int64 of every point and the number of rows H: the rank of its ring id
    among the ids present, so rows follow ring-id order. ``ring``: (N,) ids, N > 0."""
    key = np.asarray(ring, dtype=np.int64)
    lo = int(key.min())
    if int(key.max()) - lo < max(65536, 4 * len(key)):
        present = np.bincount(key - lo) > 0
        return (np.cumsum(present) - 1)[key - lo], int(np.count_nonzero(present))
    ids, row = np.unique(key, return_inverse=True)
    return row.astype(np.int64).reshape(-1), len(ids)


@numba.njit(cache=True)
def ring_order(row, n_rows):  # pragma: no cover - compiled
    """(N,) int64 indices that sort ``row`` (N,) int64, values in [0, n_rows), stably:
    each ring keeps its scan order (a counting sort: the stable argsort, in O(N))."""
    start = np.zeros(n_rows + 1, dtype=np.int64)
    for i in range(row.shape[0]):
        start[row[i] + 1] += 1
    for r in range(n_rows):
        start[r + 1] += start[r]
    order = np.empty(row.shape[0], dtype=np.int64)
    for i in range(row.shape[0]):
        order[start[row[i]]] = i
        start[row[i]] += 1
    return order


@numba.njit(cache=True)
def distinct_per_block(keys, bounds, n_keys):  # pragma: no cover - compiled
    """(B,) int64 the number of distinct ``keys`` (N,) int64, values in [0, n_keys), in
    every block ``keys[bounds[k]:bounds[k + 1]]`` (``len(np.unique(block))``)."""
    seen = np.full(n_keys, -1, dtype=np.int64)
    out = np.zeros(bounds.shape[0] - 1, dtype=np.int64)
    for k in range(out.shape[0]):
        for i in range(bounds[k], bounds[k + 1]):
            if seen[keys[i]] != k:
                seen[keys[i]] = k
                out[k] += 1
    return out


@numba.njit(cache=True)
def _ring_time_steps(t, order, row):  # pragma: no cover - compiled
    """The positive time steps (s) between consecutive points of a ring, in scan order."""
    out = np.empty(max(order.shape[0] - 1, 0))
    k = 0
    for j in range(1, order.shape[0]):
        a, b = order[j - 1], order[j]
        if row[a] == row[b]:
            dt = t[b] - t[a]
            if dt > 0:
                out[k] = dt
                k += 1
    return out[:k]


@identity_memo
def ring_layout(ring: np.ndarray) -> tuple[np.ndarray, int, np.ndarray]:
    """:func:`ring_rows` and :func:`ring_order` of ``ring`` (N,): ``(row, H, order)``,
    read-only, memoised (:mod:`planodom.extraction.memo`): they depend on the scan's
    ring field alone, not on the deskewed points, so an epoch's extractions of one scan
    (up to three with ``odometry.deskew_iterations``) compute them once."""
    row, H = ring_rows(ring)
    return read_only(row), H, read_only(ring_order(row, H))


@identity_memo
def grid_indices(
    ring: np.ndarray, t: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray | None, int, int]:
    """Row (N,) and column (N,) of every point and the grid size (H, W) (module
    docstring); column None (W = 0) when the times are unusable. Read-only and memoised
    (:mod:`planodom.extraction.memo`): they depend on the scan's ring and times alone."""
    row, H, order = ring_layout(ring)
    counts = np.bincount(row, minlength=H)
    if t is None or len(t) <= 1:
        return row, None, H, 0
    t = np.ascontiguousarray(t, dtype=np.float64)
    pos = _ring_time_steps(t, order, row)
    if len(pos) < len(ring) // 4:
        return row, None, H, 0
    step = median(pos)
    col = np.rint((t - t.min()) / step).astype(np.int64)
    if col.max() >= 4 * counts.max() + 16:
        return row, None, H, 0
    return row, read_only(col), H, int(col.max()) + 1


@identity_memo
def point_grid(points: np.ndarray, row: np.ndarray, col: np.ndarray, H: int, W: int) -> np.ndarray:
    """(H, W, 3) the grid of ``points`` (N, 3) float64 at the pixels ``(row, col)`` (N,)
    (:func:`grid_indices`; :func:`fill_grid`), read-only and memoised
    (:mod:`planodom.extraction.memo`): an extraction's range image and the RANSAC
    agreement check of the same points (:mod:`.agreement`) share it."""
    return read_only(fill_grid(points, row * W + col, H * W).reshape(H, W, 3))


@numba.njit(cache=True)
def fill_grid(points, flat, n_pix):  # pragma: no cover - compiled
    """(n_pix, 3) the point of every pixel ``flat`` (N,): the first in scan order; NaN
    where a pixel has none."""
    P = np.full((n_pix, 3), np.nan)
    for i in range(flat.shape[0] - 1, -1, -1):
        P[flat[i], 0] = points[i, 0]
        P[flat[i], 1] = points[i, 1]
        P[flat[i], 2] = points[i, 2]
    return P


@numba.njit(cache=True)
def near_pairs(label, n_pieces, gap_cols):  # pragma: no cover - compiled
    """Step 3's candidate pairs: ``a * n_pieces + b`` (unsorted, may repeat) for pieces
    a != b of ``label`` (H, W) (-1: none) with a pixel of b at (r + dr, c + dc) of one of
    a: dr in -2..2 (a ring may be missing between two pieces; every second column at
    |dr| = 2), dc in 0..gap_cols (from 1 unless dr > 0), columns wrapping.

    A window is walked by jumps, not column by column (inside a plane it is one jump per
    row): per row and column stride s (1, or 2 at |dr| = 2), columns unrolled past W for
    the wrap, ``first[s - 1, r, x]`` is the first column x, x + s, ... with a piece and
    ``other[s - 1, r, x]`` the first column after x (same stride) with another piece.
    """
    H, W = label.shape
    L = W + gap_cols + 1
    far = L + 2  # no such column
    first = np.full((2, H, L + 2), far, dtype=np.int64)
    other = np.full((2, H, L + 2), far, dtype=np.int64)
    wrap = np.arange(L) % W
    for s in range(2):
        for r in range(H):
            for x in range(L - 1, -1, -1):
                lab = label[r, wrap[x]]
                first[s, r, x] = x if lab >= 0 else first[s, r, x + s + 1]
                y = first[s, r, x + s + 1]
                if y < L and lab >= 0:
                    other[s, r, x] = y if label[r, wrap[y]] != lab else other[s, r, y]
    n = _walk_pairs(label, n_pieces, gap_cols, first, other, wrap, np.empty(0, dtype=np.int64))
    out = np.empty(n, dtype=np.int64)
    _walk_pairs(label, n_pieces, gap_cols, first, other, wrap, out)
    return out


@numba.njit(cache=True)
def _walk_pairs(label, n_pieces, gap_cols, first, other, wrap, out):
    # pragma: no cover - compiled
    """The walk of :func:`near_pairs`: the number of pairs, written to ``out`` unless it
    is empty (a counting pass first: growing ``out`` inside the loop is ~5x slower)."""
    H, W = label.shape
    fill = out.shape[0] > 0
    n = 0
    for r in range(H):
        for c in range(W):
            a = label[r, c]
            if a < 0:
                continue
            last = -1
            for dr in range(-2, 3):
                r2 = r + dr
                if r2 < 0 or r2 >= H:
                    continue
                s = 1 if abs(dr) == 2 else 0
                x = first[s, r2, c if dr > 0 else c + 1]
                while x <= c + gap_cols:
                    b = label[r2, wrap[x]]
                    if b != a and b != last:
                        last = b
                        if fill:
                            out[n] = a * n_pieces + b
                        n += 1
                    x = other[s, r2, x]
    return n


@numba.njit(cache=True)
def assign_points(points, row, col, label, normal, offset, tol, offsets):
    # pragma: no cover - compiled
    """Step 4 of :mod:`.rangeimage`: the plane (N,) int64 of every point, -1 for none:
    the first plane among
    its pixel's ``offsets`` (9, 2) neighbours in ``label`` (H, W) that it lies within
    ``tol`` of."""
    H, W = label.shape
    owner = np.full(points.shape[0], -1, dtype=np.int64)
    for i in range(points.shape[0]):
        for m in range(offsets.shape[0]):
            r2 = row[i] + offsets[m, 0]
            if r2 < 0 or r2 >= H:
                continue
            c2 = col[i] + offsets[m, 1]  # offsets are -1, 0 or 1
            g = label[r2, c2 + W if c2 < 0 else (c2 - W if c2 >= W else c2)]
            if g < 0:
                continue
            res = (
                points[i, 0] * normal[g, 0]
                + points[i, 1] * normal[g, 1]
                + points[i, 2] * normal[g, 2]
                + offset[g]
            )
            if abs(res) <= tol:
                owner[i] = g
                break
    return owner


@numba.njit(cache=True)
def plane_members(owner, n_planes):  # pragma: no cover - compiled
    """The points of every plane, ascending: ``idx`` (M,) and ``bounds`` (C + 1,), plane k
    holding ``idx[bounds[k]:bounds[k + 1]]``."""
    bounds = np.zeros(n_planes + 1, dtype=np.int64)
    for i in range(owner.shape[0]):
        if owner[i] >= 0:
            bounds[owner[i] + 1] += 1
    for k in range(n_planes):
        bounds[k + 1] += bounds[k]
    fill = bounds[:-1].copy()
    idx = np.empty(bounds[n_planes], dtype=np.int64)
    for i in range(owner.shape[0]):
        g = owner[i]
        if g >= 0:
            idx[fill[g]] = i
            fill[g] += 1
    return idx, bounds
