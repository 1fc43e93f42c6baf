"""Planes of a ringed 3D scan by region growing on its range image.

A spinning lidar's points form a grid, one row per ring and one column per firing
(:mod:`.grid`; without usable times there are no columns and the caller uses RANSAC).

1. Pixel normals: ``n = t_h x t_v`` with the row tangent ``t_h = sum_k k (p[c+k] - p[c-k])``,
   ``k = 1..region_window`` (columns wrap) and the column tangent ``t_v = p[r+S] - p[r-S]``
   (``S`` = 1 unless too noisy, see below; :mod:`.normals`).
   Their predicted angular error is ``e = sigma sqrt(2 sum k^2 / |t_h|^2 + 2 / |t_v|^2)``.
2. Grid edges (right and down neighbours) join two pixels when their normals are within
   ``region_normal_floor_deg + region_normal_sigmas * sqrt(e_i^2 + e_j^2)``, each point
   lies within ``tol + region_normal_sigmas * e * |p_i - p_j|`` of the other's tangent
   plane (``tol = max(member_sigma_factor * sigma, tolerance_floor_m)``) and the points
   are at most ``max(min_gap_m, gap_range_ratio * range * max(1, a / step))`` apart (the
   gap rule, below). Connected components of
   the pixel graph (union-find) with ``min_plane_points / 2`` pixels or more,
   an RMS residual within ``max(max_rms_sigma_factor * sigma, rms_floor_m)`` of their
   TLS plane (two-pass centred moments, batched eigen-solver) and a minor width of
   ``min_plane_width_m`` (not a line) are plane pieces, numbered in the order of their
   first pixel (row-major).
3. Pieces whose pixels come within ``cluster_gap_deg`` (columns) and two rows of each
   other in the grid (so that
   a pole in front of a wall does not split it) and whose planes agree (normals within
   ``region_merge_deg + 3 (sigma / sqrt(l2_a) + sigma / sqrt(l2_b))``, each centroid within
   ``tol`` of the other's plane) are merged, and refit from their moments; with
   ``region_merge: reach`` also pieces anywhere whose bounding circles come within
   ``plane_gap_m`` (:func:`within_reach`): the floor of a corridor, seen ahead and behind
   between its walls, is one plane (as in :mod:`.organised`), not one per stretch.
4. Every point (also points that shared a pixel, or had no normal) joins the plane of
   its pixel, or else of its 4, or else of its diagonal grid neighbours, that it lies
   within ``tol`` of. These sets are the candidates (the caller refits them robustly).

The gap rule is a scan line's (``min_gap_m``, ``gap_range_ratio``): consecutive points
one native column ``step`` apart in angle (``2 pi / W``) on a plane seen at incidence
``i`` are ``range * step / sin(i)`` apart, so the ratio joins planes seen at more than
``asin(step / gap_range_ratio)`` (3.5 deg at 1024 columns). Two neighbouring pixels whose
rays are ``a`` apart (rows: the beam spacing) get the same incidence limit: the ratio
scaled by ``a / step``. Unscaled, a sparse lidar lost its floor and ceiling: a 16-beam
unit's rows are 2 deg apart against 0.7 deg columns (512), so on a floor 1.8 m below
the sensor, rows 8 and 9.5 m away are 1.4 m apart, over the 1 m limit, and the floor
grew one piece per row, each a line (measured on an indoor 16-beam world at 6 mm: floor
and ceiling missing from 10 planes of 11 true surfaces; with the scaling both found).
Dense lidars (rows closer than the columns, :func:`row_spacing`) are unchanged. Long
edges admit more (their tangent-plane allowance grows with the length), so on a sparse
grid a piece over the RMS limit is trimmed to its plane once (:func:`_trim_pieces`)
before the test, not dropped. ``region_gap: range`` keeps the unscaled rule (no trim).

Region growing needs pixel normals better than the angle between two surfaces; when the
median predicted pixel normal error exceeds ``region_max_normal_error_deg`` (high noise,
or a sparse grid), the column tangent is taken between rows farther apart
(:func:`pixel_normals`: ``r +- S``, ``S`` = 2, 3, ...: a 64-beam lidar's rows are 0.4 deg
apart and at 2 cm they gave 111 RANSAC fragments of 26 surfaces instead of grown
planes); when no row step gets there :func:`range_image_candidates` returns None and the
caller falls back to RANSAC (:mod:`.candidates`).

The passes over pixels and points (ring sort, pixel normals, edge tests with union-find,
piece moments, neighbour pairs, point assignment) are compiled with numba: each is a
short loop over ~3 * 10^4 pixels or points with a few branches, where numpy needed tens
of full-grid temporaries (the grid shifted by every window offset) and a sparse graph,
and union-find is sequential. Their arithmetic follows the formulas above term by term
(tests/extraction/test_lidar.py checks them against whole-grid numpy and scipy's
connected components).
"""

from __future__ import annotations

import numba
import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction.kernels import components, find_root
from planodom.extraction.lidar.grid import (
    assign_points,
    grid_indices,
    near_pairs,
    plane_members,
    point_grid,
)
from planodom.extraction.lidar.normals import pixel_normals, row_chords, unit_rays
from planodom.extraction.memo import float64_c
from planodom.extraction.noise import member_tolerance, rms_limit
from planodom.geometry import row_norms

#: Step 4's pixel order, (row, column) offsets: own pixel, the 4, the diagonal neighbours.
_NEIGHBOURS = np.array(
    [(0, 0), (0, -1), (0, 1), (-1, 0), (1, 0), (-1, -1), (-1, 1), (1, -1), (1, 1)],
    dtype=np.int64,
)


def range_image_candidates(
    points: np.ndarray,
    ring: np.ndarray,
    t: np.ndarray | None,
    sigma: float,
    config: ExtractionConfig,
    viewpoint: np.ndarray,
) -> list[np.ndarray] | None:
    """Candidate inlier sets (indices into ``points`` (N, 3), metres), or None when the
    grid has no columns or the pixel normals are too noisy for region growing (module
    docstring). ``viewpoint`` (3,) m: where the ranges are measured from (gap rule)."""
    tol = member_tolerance(config, sigma)
    row, col, H, W = grid_indices(ring, t)
    if col is None:  # no usable times
        return None
    points = float64_c(points)
    # One point per pixel (the first in scan order); the others join in step 4.
    P = point_grid(points, row, col, H, W)

    # 1. Pixel normals and their predicted errors.
    normals = pixel_normals(P, sigma, tol, config, viewpoint)
    if normals is None:
        return None
    n, e, ok = normals
    ks = float(config.region_normal_sigmas)
    if np.count_nonzero(ok) < config.min_plane_points:
        return []

    # 2. Edges between right and lower neighbours, connected components, flat pieces.
    step = 2.0 * np.pi / W  # rad, a column
    sparse = config.region_gap == "incidence" and row_spacing(P, viewpoint) > step
    piece, C = _grow_pieces(
        P, n, e, ok, float(tol), ks, float(np.radians(config.region_normal_floor_deg)),
        float(config.min_gap_m), float(config.gap_range_ratio),
        np.ascontiguousarray(viewpoint, dtype=np.float64), max(3, config.min_plane_points // 2),
        step if sparse else 0.0,
    )  # fmt: skip
    pieces = _flat_pieces(P, piece, C, sigma, config, sparse)
    if pieces is None:
        return []
    # 3. Merge pieces that are near in the grid and agree on their plane.
    label, normal, offset, C = _merge_pieces(*pieces, sigma, tol, config)
    # 4. Every point joins a plane of its pixel's 3 x 3 neighbourhood: own pixel first,
    # then the 4 and the diagonal neighbours; a point takes the first plane it lies
    # within tol of (pixels are small, so the nearest in practice).
    owner = assign_points(
        points, row, col, np.ascontiguousarray(label, dtype=np.int64), np.ascontiguousarray(normal),
        offset, float(tol), _NEIGHBOURS,
    )  # fmt: skip
    idx, bounds = plane_members(owner, C)
    sizes = np.diff(bounds)
    return [idx[bounds[k] : bounds[k + 1]] for k in range(C) if sizes[k] >= config.min_plane_points]


def row_spacing(P: np.ndarray, viewpoint: np.ndarray) -> float:
    """Median angle (rad) between the rays of vertically neighbouring pixels of the grid
    ``P`` (H, W, 3) (NaN: none) seen from ``viewpoint`` (3,): the beam spacing."""
    chord = row_chords(unit_rays(P, np.ascontiguousarray(viewpoint, dtype=np.float64)))
    return float(2.0 * np.arcsin(min(np.median(chord) / 2.0, 1.0))) if len(chord) else 0.0


def _flat_pieces(
    P: np.ndarray,
    piece: np.ndarray,
    C: int,
    sigma: float,
    config: ExtractionConfig,
    trim: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """End of step 2: the pieces that are planes (RMS within the limit, not lines), as
    their pixel labels (H, W) (renumbered 0..C'-1, -1 for none), counts (C',), centroids
    (C', 3), scatters (C', 3, 3), eigenvalues (C', 3) and eigenvectors (C', 3, 3)
    (ascending); None when there is none. With ``trim`` a piece over the RMS limit is
    first trimmed to its plane (:func:`_trim_pieces`)."""
    if C == 0:
        return None
    H, W = P.shape[0], P.shape[1]
    cnt, cen, sc = _piece_moments(P.reshape(-1, 3), piece, C)
    vals, vecs = np.linalg.eigh(sc)
    rms = np.sqrt(np.maximum(vals[:, 0], 0.0) / cnt)
    rough = rms > rms_limit(config, sigma)
    if trim and np.any(rough):
        tol = member_tolerance(config, sigma)
        piece = _trim_pieces(P.reshape(-1, 3), piece, rough, cen, vecs[:, :, 0], tol)
        cnt, cen, sc = _piece_moments(P.reshape(-1, 3), piece, C)
        vals, vecs = np.linalg.eigh(sc)
        cnt = np.where(cnt >= max(3, config.min_plane_points // 2), cnt, 0.0)
    # Pieces must be planes, not lines (a ring's stretch of ground has a free normal and
    # would chain-merge the ground with a wall): minor width as in min_plane_width_m.
    safe = np.maximum(cnt, 1.0)
    rms = np.sqrt(np.maximum(vals[:, 0], 0.0) / safe)
    width = 2.0 * np.sqrt(np.maximum(vals[:, 1], 0.0) / safe)
    flat_ok = (cnt > 0) & (rms <= rms_limit(config, sigma)) & (width >= config.min_plane_width_m)
    if not np.any(flat_ok):
        return None
    # Renumber the flat pieces 0..C'-1 (-1 for the others, kept at index C).
    new = np.full(C + 1, -1, dtype=np.int64)
    new[:C][flat_ok] = np.arange(np.count_nonzero(flat_ok))
    label = new[piece].reshape(H, W)
    return label, cnt[flat_ok], cen[flat_ok], sc[flat_ok], vals[flat_ok], vecs[flat_ok]


def _trim_pieces(
    Pf: np.ndarray,
    piece: np.ndarray,
    rough: np.ndarray,
    cen: np.ndarray,
    normal: np.ndarray,
    tol: float,
) -> np.ndarray:
    """``piece`` (H * W,) without the pixels (``Pf`` (H * W, 3)) of the ``rough`` (C,)
    pieces farther than ``tol`` (m) from their piece's TLS plane (centroids ``cen``
    (C, 3), unit normals (C, 3)).

    With the incidence gap rule a sparse lidar's far rows on the ground, metres apart,
    join; a few pixels of a low object among them (a kerb, a box) then pass the edge
    tests (whose tangent-plane allowance grows with the edge length) and the ground
    piece fails the RMS test as a whole (measured on an outdoor 32-beam world: the whole
    ground, 15 000 points, lost in 2 scans of 10, 21 pixels of a low object in it). One
    trim of the pixels off the plane, then the RMS test again: a curved surface keeps
    only a band within the member tolerance, which the test then judges."""
    out = piece.copy()
    idx = np.flatnonzero(piece >= 0)
    idx = idx[rough[piece[idx]]]
    g = piece[idx]
    res = np.abs(np.einsum("ij,ij->i", Pf[idx] - cen[g], normal[g]))
    out[idx[~(res <= tol)]] = -1
    return out


def _merge_pieces(
    label: np.ndarray,
    cnt: np.ndarray,
    cen: np.ndarray,
    sc: np.ndarray,
    vals: np.ndarray,
    vecs: np.ndarray,
    sigma: float,
    tol: float,
    config: ExtractionConfig,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Step 3: pieces near in the grid whose planes agree become one (connected
    components of the agreeing pairs), refit from their moments. Returns the pixel labels
    (H, W), the planes' unit normals (C, 3) and offsets (C,) and their number C."""
    C, W = len(cnt), label.shape[1]
    normal = vecs[:, :, 0]
    offset = -np.einsum("ij,ij->i", normal, cen)
    gap_cols = max(1, int(np.ceil(np.radians(config.cluster_gap_deg) / (2 * np.pi / W))))
    pairs = np.unique(near_pairs(label, C, gap_cols))
    a, b = pairs // C, pairs % C
    if config.region_merge == "reach":
        a, b = within_reach(a, b, cnt, cen, vals, config.plane_gap_m)
    if len(a) == 0:
        return label, normal, offset, C
    err = sigma / np.sqrt(np.maximum(vals[:, 1], 1e-300))
    M, merged = merge_coplanar(a, b, normal, offset, cen, err, tol, config.region_merge_deg)
    if M == C:
        return label, normal, offset, C
    cnt, cen, sc = moment_sums(merged, M, cnt, cen, sc)
    vals, vecs = np.linalg.eigh(sc)
    normal = vecs[:, :, 0]
    offset = -np.einsum("ij,ij->i", normal, cen)
    label = np.where(label >= 0, merged[np.maximum(label, 0)], -1)
    return label, normal, offset, M


def within_reach(
    a: np.ndarray,
    b: np.ndarray,
    cnt: np.ndarray,
    cen: np.ndarray,
    vals: np.ndarray,
    gap_m: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The candidate pairs ``(a, b)`` and every pair of pieces (count (C,), centroid
    (C, 3), scatter eigenvalues (C, 3) ascending) whose bounding circles (radius
    ``sqrt(3 (l1 + l2) / n)``, a uniform disc's edge) come within ``gap_m`` (m)."""
    radius = np.sqrt(3.0 * (vals[:, 2] + vals[:, 1]) / np.maximum(cnt, 1.0))
    ia, ib = np.triu_indices(len(cnt), 1)
    reach = radius[ia] + radius[ib] + gap_m
    near = row_norms(cen[ia] - cen[ib]) <= reach
    return np.r_[a, ia[near]], np.r_[b, ib[near]]


def moment_sums(
    label: np.ndarray, n_lab: int, count: np.ndarray, centroid: np.ndarray, scatter: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Count (L,), centroid (L, 3) and centred scatter (L, 3, 3) of the unions of items
    (count (C,), centroid (C, 3), scatter (C, 3, 3)) grouped by ``label`` (C,) in
    [0, n_lab) (parallel-axis theorem)."""
    cnt = np.bincount(label, count.astype(np.float64), n_lab)
    cen = (
        np.stack([np.bincount(label, count * centroid[:, k], n_lab) for k in range(3)], axis=1)
        / np.maximum(cnt, 1e-300)[:, None]
    )
    dc = centroid - cen[label]
    full = scatter + count[:, None, None] * dc[:, :, None] * dc[:, None, :]
    sc = np.stack([np.bincount(label, full[:, i, j], n_lab) for i in range(3) for j in range(3)])
    return cnt, cen, sc.T.reshape(-1, 3, 3)


@numba.njit(cache=True, error_model="numpy")
def _grow_pieces(P, normal, err, ok, tol, ks, floor, min_gap, gap_ratio, view, min_px, step):
    # pragma: no cover - compiled
    """Step 2's edges (each pixel with its right and lower neighbour) and connected
    components by union-find. ``step`` (rad): the angular step the gap ratio refers to
    (0: none; module docstring).

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
                gap = max(min_gap, gap_ratio * rng)
                if not dist <= gap and step > 0:
                    h0 = P[r2, c2, 0] - view[0]
                    h1 = P[r2, c2, 1] - view[1]
                    h2 = P[r2, c2, 2] - view[2]
                    rng2 = np.sqrt(h0 * h0 + h1 * h1 + h2 * h2)
                    # the angle between the two rays (chord of the unit rays)
                    u0, u1, u2 = g0 / rng - h0 / rng2, g1 / rng - h1 / rng2, g2 / rng - h2 / rng2
                    ang = 2.0 * np.arcsin(min(0.5 * np.sqrt(u0 * u0 + u1 * u1 + u2 * u2), 1.0))
                    gap = max(min_gap, gap_ratio * rng * max(1.0, ang / step))
                if not dist <= gap:
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


def merge_coplanar(
    a: np.ndarray,
    b: np.ndarray,
    normal: np.ndarray,
    offset: np.ndarray,
    centroid: np.ndarray,
    err: np.ndarray,
    tol: float,
    merge_deg: float,
) -> tuple[int, np.ndarray]:
    """Connected groups of coplanar pieces among the candidate pairs ``(a[i], b[i])``.

    Two pieces are one plane when their normals (C, 3) differ by at most ``merge_deg``
    plus three times the sum of their predicted normal errors ``err`` (C,), rad, and each
    centroid (C, 3), m, lies within ``tol`` (m) of the other's plane (``offset`` (C,), m).
    Returns the number of groups and the group of each piece (C,).
    """
    cosang = np.abs(np.einsum("ij,ij->i", normal[a], normal[b]))
    lim = np.radians(merge_deg) + 3.0 * (err[a] + err[b])
    same = cosang >= np.cos(np.minimum(lim, np.pi / 2))
    same &= np.abs(np.einsum("ij,ij->i", normal[a], centroid[b]) + offset[a]) <= tol
    same &= np.abs(np.einsum("ij,ij->i", normal[b], centroid[a]) + offset[b]) <= tol
    M, merged = components(a[same].astype(np.int64), b[same].astype(np.int64), len(normal))
    return int(M), merged
