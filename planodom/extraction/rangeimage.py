"""Planes of a ringed 3D scan by region growing on its range image.

A spinning lidar's points form a grid: one row per ring (rows in ring-id order, which a
lidar driver's ``ring`` field follows: lowest beam first, or highest) and one column per
firing. The column of a point is taken from its time within its ring,
``round((t - t_min) / dt)`` with ``dt`` the median time step between consecutive points
of a ring (dropped no-return beams leave empty pixels), or, without usable times (all zero:
a snapshot), from its azimuth about the viewpoint (as many columns as the fullest ring has
points) when ``region_azimuth_columns``, else the caller uses RANSAC. Only
what a recorded cloud with rings has is used: ``ring``, the points' order within a ring,
``t``.

1. Pixel normals: ``n = t_h x t_v`` with the row tangent ``t_h = sum_k k (p[c+k] - p[c-k])``,
   ``k = 1..region_window`` (columns wrap) and the column tangent ``t_v = p[r+1] - p[r-1]``.
   Their predicted angular error is ``e = sigma sqrt(2 sum k^2 / |t_h|^2 + 2 / |t_v|^2)``.
2. Grid edges (right and down neighbours) join two pixels when their normals are within
   ``region_normal_floor_deg + region_normal_sigmas * sqrt(e_i^2 + e_j^2)``, each point
   lies within ``tol + region_normal_sigmas * e * |p_i - p_j|`` of the other's tangent
   plane (``tol = max(member_sigma_factor * sigma, tolerance_floor_m)``) and the points
   are at most ``max(min_gap_m, gap_range_ratio * range)`` apart. Connected components of
   the pixel graph (union-find) with ``min_plane_points / 2`` pixels or more,
   an RMS residual within ``max(max_rms_sigma_factor * sigma, rms_floor_m)`` of their
   TLS plane (two-pass centred moments, batched eigen-solver) and a minor width of
   ``min_plane_width_m`` (not a line) are plane pieces, numbered in the order of their
   first pixel (row-major).
3. Pieces whose pixels come within ``cluster_gap_deg`` (columns) and two rows of each
   other in the grid (so that
   a pole in front of a wall does not split it) and whose planes agree (normals within
   ``region_merge_deg + 3 (sigma / sqrt(l2_a) + sigma / sqrt(l2_b))``, each centroid within
   ``tol`` of the other's plane) are merged, and refit from their moments.
4. Every point (also points that shared a pixel, or had no normal) joins the plane of
   its pixel, or else of its 4, or else of its diagonal grid neighbours, that it lies
   within ``tol`` of. These sets are the candidates (the caller refits them robustly).

Region growing needs pixel normals better than the angle between two surfaces; when the
median predicted pixel normal error exceeds ``region_max_normal_error_deg`` (high noise,
or a sparse grid) :func:`range_image_candidates` returns None and the caller falls back
to RANSAC (:mod:`.lidar`).

The passes over pixels and points (ring sort, pixel normals, edge tests with union-find,
piece moments, neighbour pairs, point assignment) are compiled with numba: each is a
short loop over ~3 * 10^4 pixels or points with a few branches, where numpy needed tens
of full-grid temporaries (the grid shifted by every window offset) and a sparse graph,
and union-find is sequential. Their arithmetic follows the formulas above term by term
(tests/test_extraction_lidar.py checks them against whole-grid numpy and scipy's
connected components).
"""

from __future__ import annotations

import numba
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from planodom.config import ExtractionConfig
from planodom.extraction.grouping import moment_sums
from planodom.extraction.kernels import find_root

#: Step 4's pixel order, (row, column) offsets: own pixel, the 4, the diagonal neighbours.
_NEIGHBOURS = np.array(
    [(0, 0), (0, -1), (0, 1), (-1, 0), (1, 0), (-1, -1), (-1, 1), (1, -1), (1, 1)],
    dtype=np.int64,
)


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


def grid_indices(
    points: np.ndarray,
    ring: np.ndarray,
    t: np.ndarray | None,
    viewpoint: np.ndarray,
    azimuth: bool = True,
) -> tuple[np.ndarray, np.ndarray | None, int, int]:
    """Row (N,), column (N,) of every point and the grid size (H, W) (module docstring);
    column None (W = 0) when the times are unusable and ``azimuth`` is False."""
    row, H = ring_rows(ring)
    counts = np.bincount(row, minlength=H)
    col = None
    if t is not None and len(t) > 1:
        t = np.ascontiguousarray(t, dtype=np.float64)
        pos = _ring_time_steps(t, ring_order(row, H), row)
        if len(pos) >= len(points) // 4:
            step = float(np.median(pos))
            c = np.rint((t - t.min()) / step).astype(np.int64)
            if c.max() < 4 * counts.max() + 16:
                col = c
    if col is None and not azimuth:
        return row, None, H, 0
    if col is None:
        W = int(counts.max())
        rel = points - viewpoint
        az = np.arctan2(rel[:, 1], rel[:, 0])
        col = np.floor((az + np.pi) / (2.0 * np.pi) * W).astype(np.int64) % W
    return row, col, H, int(col.max()) + 1


@numba.njit(cache=True)
def _fill_grid(points, flat, n_pix):  # pragma: no cover - compiled
    """(n_pix, 3) the point of every pixel ``flat`` (N,): the first in scan order; NaN
    where a pixel has none."""
    P = np.full((n_pix, 3), np.nan)
    for i in range(flat.shape[0] - 1, -1, -1):
        P[flat[i], 0] = points[i, 0]
        P[flat[i], 1] = points[i, 1]
        P[flat[i], 2] = points[i, 2]
    return P


@numba.njit(cache=True, error_model="numpy")
def _pixel_normals(P, K, sigma, tol, ks):  # pragma: no cover - compiled
    """Step 1 on the grid ``P`` (H, W, 3) (NaN: no point), window half-width ``K``.

    Returns the unit normals (H, W, 3) (0 where not ``ok``), their predicted errors
    (H, W) (rad; inf where not ``ok``) and ``ok`` (H, W): the pixel has a normal, and the
    ends of its window (the columns c +- K, the rows r +- 1) lie within
    ``tol + ks e |q - p|`` of its tangent plane (a window across an edge or a corner has
    a mixed normal). A pixel without a point between pixels that have one gets a normal
    too (counted in the median error); it joins no edge.
    """
    H, W = P.shape[0], P.shape[1]
    normal = np.zeros((H, W, 3))
    err = np.full((H, W), np.inf)
    ok = np.zeros((H, W), dtype=np.bool_)
    s2 = 0.0
    for k in range(1, K + 1):
        s2 += k * k
    s2 *= 2.0
    q = np.empty((4, 3))
    wrap = np.arange(-K, W + K) % W  # column c + k is wrap[c + k + K]
    for r in range(1, H - 1):  # the first and last rows have no column tangent
        for c in range(W):
            p0, p1, p2 = P[r, c, 0], P[r, c, 1], P[r, c, 2]
            h0 = h1 = h2 = 0.0
            for k in range(1, K + 1):
                a = wrap[c + k + K]
                b = wrap[c - k + K]
                h0 += k * (P[r, a, 0] - P[r, b, 0])
                h1 += k * (P[r, a, 1] - P[r, b, 1])
                h2 += k * (P[r, a, 2] - P[r, b, 2])
            v0 = P[r + 1, c, 0] - P[r - 1, c, 0]
            v1 = P[r + 1, c, 1] - P[r - 1, c, 1]
            v2 = P[r + 1, c, 2] - P[r - 1, c, 2]
            n0 = h1 * v2 - h2 * v1
            n1 = h2 * v0 - h0 * v2
            n2 = h0 * v1 - h1 * v0
            nn = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
            lh2 = h0 * h0 + h1 * h1 + h2 * h2
            lv2 = v0 * v0 + v1 * v1 + v2 * v2
            e = sigma * np.sqrt(s2 / lh2 + 2.0 / lv2)
            if not (np.isfinite(nn) and nn > 0 and np.isfinite(e)):
                continue
            n0, n1, n2 = n0 / nn, n1 / nn, n2 / nn
            a = wrap[c + 2 * K]
            b = wrap[c]
            for j in range(3):
                q[0, j] = P[r, a, j]
                q[1, j] = P[r, b, j]
                q[2, j] = P[r + 1, c, j]
                q[3, j] = P[r - 1, c, j]
            good = True
            for m in range(4):
                d0, d1, d2 = q[m, 0] - p0, q[m, 1] - p1, q[m, 2] - p2
                res = abs(d0 * n0 + d1 * n1 + d2 * n2)
                if res > tol + ks * e * np.sqrt(d0 * d0 + d1 * d1 + d2 * d2):
                    good = False
                    break
            if good:
                ok[r, c] = True
                err[r, c] = e
                normal[r, c, 0] = n0
                normal[r, c, 1] = n1
                normal[r, c, 2] = n2
    return normal, err, ok


@numba.njit(cache=True, error_model="numpy")
def _grow_pieces(P, normal, err, ok, tol, ks, floor, min_gap, gap_ratio, view, min_px):
    # pragma: no cover - compiled
    """Step 2's edges (each pixel with its right and lower neighbour) and connected
    components by union-find.

    Returns the piece (H * W,) int64 of every pixel (-1 unless its component has
    ``min_px`` pixels or more), pieces numbered 0.. in the order of their first pixel
    (row-major), and the number of pieces.
    """
    H, W = P.shape[0], P.shape[1]
    parent = np.arange(H * W)
    half_pi = np.pi / 2
    # cos is decreasing on [0, pi / 2] and the angle limit is floor or more: normals
    # within floor of each other pass without computing the limit's cosine.
    cos_floor = np.cos(min(floor, half_pi))
    for r in range(H):
        for c in range(W):
            if not ok[r, c]:
                continue
            i = r * W + c
            ei = err[r, c]
            for side in range(2):
                r2, c2 = (r, c + 1 if c + 1 < W else 0) if side == 0 else (r + 1, c)
                if r2 >= H or not ok[r2, c2]:
                    continue
                ej = err[r2, c2]
                d0 = P[r2, c2, 0] - P[r, c, 0]
                d1 = P[r2, c2, 1] - P[r, c, 1]
                d2 = P[r2, c2, 2] - P[r, c, 2]
                dist = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                cosang = abs(
                    normal[r, c, 0] * normal[r2, c2, 0]
                    + normal[r, c, 1] * normal[r2, c2, 1]
                    + normal[r, c, 2] * normal[r2, c2, 2]
                )
                if not cosang >= cos_floor:
                    eij = np.sqrt(ei * ei + ej * ej)
                    if not cosang >= np.cos(min(floor + ks * eij, half_pi)):
                        continue
                ri = d0 * normal[r, c, 0] + d1 * normal[r, c, 1] + d2 * normal[r, c, 2]
                rj = d0 * normal[r2, c2, 0] + d1 * normal[r2, c2, 1] + d2 * normal[r2, c2, 2]
                if not (abs(ri) <= tol + ks * ei * dist and abs(rj) <= tol + ks * ej * dist):
                    continue
                g0 = P[r, c, 0] - view[0]
                g1 = P[r, c, 1] - view[1]
                g2 = P[r, c, 2] - view[2]
                rng = np.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
                if not dist <= max(min_gap, gap_ratio * rng):
                    continue
                a = find_root(parent, i)
                b = find_root(parent, r2 * W + c2)
                if a != b:  # the smaller root wins: deterministic
                    if a < b:
                        parent[b] = a
                    else:
                        parent[a] = b
    okf = ok.reshape(H * W)
    size = np.zeros(H * W, dtype=np.int64)
    for i in range(H * W):
        if okf[i]:
            size[find_root(parent, i)] += 1
    piece = np.full(H * W, -1, dtype=np.int64)
    number = np.full(H * W, -1, dtype=np.int64)
    n_pieces = 0
    for i in range(H * W):
        if not okf[i]:
            continue
        root = find_root(parent, i)
        if size[root] < min_px:
            continue
        if number[root] < 0:
            number[root] = n_pieces
            n_pieces += 1
        piece[i] = number[root]
    return piece, n_pieces


@numba.njit(cache=True)
def _piece_moments(P, piece, n_pieces):  # pragma: no cover - compiled
    """Pixel count (C,), centroid (C, 3) and centred scatter (C, 3, 3) of every piece
    (``P`` (H * W, 3), ``piece`` (H * W,)), two-pass so that exact data stays exact."""
    cnt = np.zeros(n_pieces)
    cen = np.zeros((n_pieces, 3))
    for i in range(piece.shape[0]):
        g = piece[i]
        if g >= 0:
            cnt[g] += 1.0
            for k in range(3):
                cen[g, k] += P[i, k]
    for g in range(n_pieces):
        for k in range(3):
            cen[g, k] /= max(cnt[g], 1.0)
    sc = np.zeros((n_pieces, 3, 3))
    for i in range(piece.shape[0]):
        g = piece[i]
        if g >= 0:
            q0, q1, q2 = P[i, 0] - cen[g, 0], P[i, 1] - cen[g, 1], P[i, 2] - cen[g, 2]
            sc[g, 0, 0] += q0 * q0
            sc[g, 0, 1] += q0 * q1
            sc[g, 0, 2] += q0 * q2
            sc[g, 1, 1] += q1 * q1
            sc[g, 1, 2] += q1 * q2
            sc[g, 2, 2] += q2 * q2
    for g in range(n_pieces):
        sc[g, 1, 0] = sc[g, 0, 1]
        sc[g, 2, 0] = sc[g, 0, 2]
        sc[g, 2, 1] = sc[g, 1, 2]
    return cnt, cen, sc


@numba.njit(cache=True)
def _near_pairs(label, n_pieces, gap_cols):  # pragma: no cover - compiled
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
    """The walk of :func:`_near_pairs`: the number of pairs, written to ``out`` unless it
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
def _assign_points(points, row, col, label, normal, offset, tol, offsets):
    # pragma: no cover - compiled
    """Step 4: the plane (N,) int64 of every point, -1 for none: the first plane among
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
def _members(owner, n_planes):  # pragma: no cover - compiled
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


def range_image_candidates(
    points: np.ndarray,
    ring: np.ndarray,
    t: np.ndarray | None,
    sigma: float,
    config: ExtractionConfig,
    viewpoint: np.ndarray,
) -> list[np.ndarray] | None:
    """Candidate inlier sets (indices into ``points`` (N, 3), metres), or None when the
    pixel normals are too noisy for region growing (module docstring)."""
    tol = max(config.member_sigma_factor * sigma, config.tolerance_floor_m)
    row, col, H, W = grid_indices(points, ring, t, viewpoint, config.region_azimuth_columns)
    if col is None:  # no usable times and azimuth columns not enabled
        return None
    points = np.ascontiguousarray(points, dtype=np.float64)
    view = np.ascontiguousarray(viewpoint, dtype=np.float64)
    # One point per pixel (the first in scan order); the others join in step 4.
    P = _fill_grid(points, row * W + col, H * W).reshape(H, W, 3)

    # 1. Pixel normals and their predicted errors.
    K = max(1, int(config.region_window))
    ks = float(config.region_normal_sigmas)
    n, e, ok = _pixel_normals(P, K, float(sigma), float(tol), ks)
    if np.count_nonzero(ok) < config.min_plane_points:
        return []
    if np.degrees(np.median(e[ok])) > config.region_max_normal_error_deg:
        return None

    # 2. Edges between right and lower neighbours, connected components, flat pieces.
    min_px = max(3, config.min_plane_points // 2)
    piece, C = _grow_pieces(
        P, n, e, ok, float(tol), ks, float(np.radians(config.region_normal_floor_deg)),
        float(config.min_gap_m), float(config.gap_range_ratio), view, min_px,
    )  # fmt: skip
    if C == 0:
        return []
    cnt, cen, sc = _piece_moments(P.reshape(-1, 3), piece, C)
    vals, vecs = np.linalg.eigh(sc)
    rms = np.sqrt(np.maximum(vals[:, 0], 0.0) / cnt)
    max_rms = max(config.max_rms_sigma_factor * sigma, config.rms_floor_m)
    # Pieces must be planes, not lines (a ring's stretch of ground has a free normal and
    # would chain-merge the ground with a wall): minor width as in min_plane_width_m.
    width = 2.0 * np.sqrt(np.maximum(vals[:, 1], 0.0) / cnt)
    flat_ok = (rms <= max_rms) & (width >= config.min_plane_width_m)
    if not np.any(flat_ok):
        return []
    # Renumber the flat pieces 0..C'-1 (-1 for the others, kept at index C).
    new = np.full(C + 1, -1, dtype=np.int64)
    new[:C][flat_ok] = np.arange(np.count_nonzero(flat_ok))
    cnt, cen, sc, vals, vecs = cnt[flat_ok], cen[flat_ok], sc[flat_ok], vals[flat_ok], vecs[flat_ok]
    C = len(cnt)
    label = new[piece].reshape(H, W)

    # 3. Merge pieces that are near in the grid and agree on their plane.
    normal = vecs[:, :, 0]
    offset = -np.einsum("ij,ij->i", normal, cen)
    gap_cols = max(1, int(np.ceil(np.radians(config.cluster_gap_deg) / (2 * np.pi / W))))
    pairs = np.unique(_near_pairs(label, C, gap_cols))
    if len(pairs):
        a, b = pairs // C, pairs % C
        err = sigma / np.sqrt(np.maximum(vals[:, 1], 1e-300))
        cosang = np.abs(np.einsum("ij,ij->i", normal[a], normal[b]))
        lim = np.radians(config.region_merge_deg) + 3.0 * (err[a] + err[b])
        same = cosang >= np.cos(np.minimum(lim, np.pi / 2))
        same &= np.abs(np.einsum("ij,ij->i", normal[a], cen[b]) + offset[a]) <= tol
        same &= np.abs(np.einsum("ij,ij->i", normal[b], cen[a]) + offset[b]) <= tol
        a, b = a[same], b[same]
        g = coo_matrix((np.ones(len(a)), (a, b)), shape=(C, C))
        M, merged = connected_components(g, directed=False)
        if M < C:
            cnt, cen, sc = moment_sums(merged, M, cnt, cen, sc)
            vals, vecs = np.linalg.eigh(sc)
            normal = vecs[:, :, 0]
            offset = -np.einsum("ij,ij->i", normal, cen)
            label = np.where(label >= 0, merged[np.maximum(label, 0)], -1)
            C = M

    # 4. Every point joins a plane of its pixel's 3 x 3 neighbourhood: own pixel first,
    # then the 4 and the diagonal neighbours; a point takes the first plane it lies
    # within tol of (pixels are small, so the nearest in practice).
    owner = _assign_points(
        points, row, col, np.ascontiguousarray(label, dtype=np.int64), np.ascontiguousarray(normal),
        offset, float(tol), _NEIGHBOURS,
    )  # fmt: skip
    idx, bounds = _members(owner, C)
    sizes = np.diff(bounds)
    return [idx[bounds[k] : bounds[k + 1]] for k in range(C) if sizes[k] >= config.min_plane_points]
