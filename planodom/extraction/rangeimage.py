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
   the pixel graph (scipy.sparse.csgraph) with ``min_plane_points / 2`` pixels or more
   an RMS residual within ``max(max_rms_sigma_factor * sigma, rms_floor_m)`` of their
   TLS plane (moments by bincount, batched eigen-solver) and a minor width of
   ``min_plane_width_m`` (not a line) are plane pieces.
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
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from planodom.config import ExtractionConfig
from planodom.extraction.grouping import moment_sums

_PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
_SYM33 = np.array([0, 1, 2, 1, 3, 4, 2, 4, 5])


def grid_indices(
    points: np.ndarray,
    ring: np.ndarray,
    t: np.ndarray | None,
    viewpoint: np.ndarray,
    azimuth: bool = True,
) -> tuple[np.ndarray, np.ndarray | None, int, int]:
    """Row (N,), column (N,) of every point and the grid size (H, W) (module docstring);
    column None (W = 0) when the times are unusable and ``azimuth`` is False."""
    key = np.asarray(ring, dtype=np.int64) - int(np.min(ring))
    present = np.bincount(key) > 0
    row = (np.cumsum(present) - 1)[key]
    H = int(np.count_nonzero(present))
    counts = np.bincount(row, minlength=H)
    rel = points - viewpoint
    col = None
    if t is not None and len(t) > 1:
        # Radix sort on small keys; stable, so each ring keeps its scan order.
        order = np.argsort(row.astype(np.uint16) if H < 65536 else row, kind="stable")
        dt = np.diff(t[order])
        same = row[order][1:] == row[order][:-1]
        pos = dt[same & (dt > 0)]
        if len(pos) >= len(points) // 4:
            step = float(np.median(pos))
            c = np.rint((t - t.min()) / step).astype(np.int64)
            if c.max() < 4 * counts.max() + 16:
                col = c
    if col is None and not azimuth:
        return row, None, H, 0
    if col is None:
        W = int(counts.max())
        az = np.arctan2(rel[:, 1], rel[:, 0])
        col = np.floor((az + np.pi) / (2.0 * np.pi) * W).astype(np.int64) % W
    return row, col, H, int(col.max()) + 1


def _shift_cols(a: np.ndarray, k: int) -> np.ndarray:
    """``a[:, (c + k) % W]`` for every column c."""
    return np.roll(a, -k, axis=1)


def _shift_rows(a: np.ndarray, k: int) -> np.ndarray:
    """``a[r + k]`` (NaN / -1 outside the grid)."""
    out = np.full_like(a, np.nan if a.dtype.kind == "f" else -1)
    if k > 0:
        out[:-k] = a[k:]
    elif k < 0:
        out[-k:] = a[:k]
    else:
        out[:] = a
    return out


def _moments(gid: np.ndarray, G: int, p: np.ndarray):
    cnt = np.bincount(gid, minlength=G).astype(np.float64)
    cen = np.stack([np.bincount(gid, p[:, k], G) for k in range(3)], axis=1)
    cen /= np.maximum(cnt, 1.0)[:, None]
    q = p - cen[gid]
    sc = np.stack([np.bincount(gid, q[:, i] * q[:, j], G) for i, j in _PAIRS], axis=1)
    return cnt, cen, sc[:, _SYM33].reshape(-1, 3, 3)


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
    flat = row * W + col
    # One point per pixel (the first in scan order); the others join in step 4.
    pix_pt = np.full(H * W, -1, dtype=np.int64)
    pix_pt[flat[::-1]] = np.arange(len(points))[::-1]
    P = np.full((H * W, 3), np.nan)
    has = pix_pt >= 0
    P[has] = points[pix_pt[has]]
    P = P.reshape(H, W, 3)

    # 1. Pixel normals and their predicted errors.
    K = max(1, int(config.region_window))
    near = {k: _shift_cols(P, k) for k in range(-K, K + 1) if k}
    near["up"], near["down"] = _shift_rows(P, 1), _shift_rows(P, -1)
    th = np.zeros((H, W, 3))
    for k in range(1, K + 1):
        th += k * (near[k] - near[-k])
    tv = near["up"] - near["down"]
    n = np.cross(th, tv)
    nn = np.linalg.norm(n, axis=2)
    lh2 = np.einsum("rci,rci->rc", th, th)
    lv2 = np.einsum("rci,rci->rc", tv, tv)
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / nn[:, :, None]
        e = sigma * np.sqrt(2.0 * sum(k * k for k in range(1, K + 1)) / lh2 + 2.0 / lv2)
    ok = np.isfinite(nn) & (nn > 0) & np.isfinite(e)
    # A pixel whose window straddles an edge or a corner has a mixed normal: the ends of
    # its window must lie within the edge test's limit of its tangent plane.
    ks = config.region_normal_sigmas
    n0 = np.where(ok[:, :, None], n, 0.0)
    e0 = np.where(ok, e, 0.0)
    for Q in (near[K], near[-K], near["up"], near["down"]):  # the window's extremes
        dq = Q - P
        res = np.abs(np.einsum("rci,rci->rc", dq, n0))
        lim = tol + ks * e0 * np.sqrt(np.einsum("rci,rci->rc", dq, dq))
        ok &= ~(res > lim)  # NaN (no neighbour) passes: edges of the grid keep their pixels
    if np.count_nonzero(ok) < config.min_plane_points:
        return []
    if np.degrees(np.median(e[ok])) > config.region_max_normal_error_deg:
        return None
    e = np.where(ok, e, np.inf)

    # 2. Edges between right and lower neighbours, connected components.
    idx = np.arange(H * W).reshape(H, W)
    floor = np.radians(config.region_normal_floor_deg)
    ks = config.region_normal_sigmas
    src, dst = [], []
    for other, oidx, Pj in (
        (lambda a: _shift_cols(a, 1), _shift_cols(idx, 1), near[1]),
        (lambda a: _shift_rows(a, 1), _shift_rows(idx, 1), near["up"]),
    ):
        nj, ej, okj = other(n), other(e), other(ok.astype(np.float64)) > 0
        both = ok & okj
        a = np.flatnonzero(both)
        pi, pj = P.reshape(-1, 3)[a], Pj.reshape(-1, 3)[a]
        ni, nj_ = n.reshape(-1, 3)[a], nj.reshape(-1, 3)[a]
        ei, ej_ = e.ravel()[a], ej.ravel()[a]
        dp = pj - pi
        dist = np.linalg.norm(dp, axis=1)
        cosang = np.abs(np.einsum("ij,ij->i", ni, nj_))
        eij = np.sqrt(ei * ei + ej_ * ej_)
        ang_ok = cosang >= np.cos(np.minimum(floor + ks * eij, np.pi / 2))
        lim_i = tol + ks * ei * dist
        lim_j = tol + ks * ej_ * dist
        pl_ok = (np.abs(np.einsum("ij,ij->i", ni, dp)) <= lim_i) & (
            np.abs(np.einsum("ij,ij->i", nj_, dp)) <= lim_j
        )
        rng = np.linalg.norm(pi - viewpoint, axis=1)
        gap_ok = dist <= np.maximum(config.min_gap_m, config.gap_range_ratio * rng)
        keep = ang_ok & pl_ok & gap_ok
        src.append(a[keep])
        dst.append(oidx.ravel()[a[keep]])
    src, dst = np.concatenate(src), np.concatenate(dst)
    graph = coo_matrix((np.ones(len(src)), (src, dst)), shape=(H * W, H * W))
    _, comp = connected_components(graph, directed=False)
    okf = ok.ravel()
    sizes = np.bincount(comp[okf], minlength=comp.max() + 1)
    min_px = max(3, config.min_plane_points // 2)
    big = sizes >= min_px
    pix_lab = np.where(okf & big[comp], comp, -1)
    sel = np.flatnonzero(pix_lab >= 0)
    if len(sel) == 0:
        return []
    uniq, lab = np.unique(pix_lab[sel], return_inverse=True)
    C = len(uniq)
    p_sel = P.reshape(-1, 3)[sel]
    cnt, cen, sc = _moments(lab, C, p_sel)
    vals, vecs = np.linalg.eigh(sc)
    rms = np.sqrt(np.maximum(vals[:, 0], 0.0) / cnt)
    max_rms = max(config.max_rms_sigma_factor * sigma, config.rms_floor_m)
    # Pieces must be planes, not lines (a ring's stretch of ground has a free normal and
    # would chain-merge the ground with a wall): minor width as in min_plane_width_m.
    width = 2.0 * np.sqrt(np.maximum(vals[:, 1], 0.0) / cnt)
    flat_ok = (rms <= max_rms) & (width >= config.min_plane_width_m)
    if not np.any(flat_ok):
        return []
    # Renumber the flat pieces 0..C'-1.
    new = np.full(C, -1, dtype=np.int64)
    new[flat_ok] = np.arange(np.count_nonzero(flat_ok))
    cnt, cen, sc, vals, vecs = cnt[flat_ok], cen[flat_ok], sc[flat_ok], vals[flat_ok], vecs[flat_ok]
    C = len(cnt)
    label = np.full(H * W, -1, dtype=np.int64)
    label[sel] = new[lab]
    label = label.reshape(H, W)

    # 3. Merge pieces that are near in the grid and agree on their plane.
    normal = vecs[:, :, 0]
    offset = -np.einsum("ij,ij->i", normal, cen)
    gap_cols = max(1, int(np.ceil(np.radians(config.cluster_gap_deg) / (2 * np.pi / W))))
    pairs = []
    for dr in (-2, -1, 0, 1, 2):  # a ring may be missing between two pieces
        for dc in range(0 if dr > 0 else 1, gap_cols + 1, 2 if abs(dr) == 2 else 1):
            other = _shift_cols(_shift_rows(label, dr), dc)
            m = (label >= 0) & (other >= 0) & (label != other)
            pairs.append(label[m] * C + other[m])
    pairs = np.unique(np.concatenate(pairs))
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

    # 4. Every point joins a plane of its pixel's 3 x 3 neighbourhood.
    owner = np.full(len(points), -1, dtype=np.int64)
    todo = np.arange(len(points))
    lab_flat = label.ravel()
    for dr, dc in ((0, 0), (0, -1), (0, 1), (-1, 0), (1, 0), (-1, -1), (-1, 1), (1, -1), (1, 1)):
        # Own pixel first, then the 4 and the diagonal neighbours: a point takes the first
        # plane it lies within tol of (pixels are small, so the nearest in practice).
        if len(todo) == 0:
            break
        r_nb = row[todo] + dr
        inside = (r_nb >= 0) & (r_nb < H)
        todo_in = todo[inside]
        nb = lab_flat[r_nb[inside] * W + (col[todo_in] + dc) % W]
        hit = nb >= 0
        ii, lab_i = todo_in[hit], nb[hit]
        r = np.abs(np.einsum("ij,ij->i", points[ii], normal[lab_i]) + offset[lab_i])
        good = r <= tol
        owner[ii[good]] = lab_i[good]
        todo = todo[owner[todo] < 0]
    assigned = np.flatnonzero(owner >= 0)
    srt = assigned[np.argsort(owner[assigned], kind="stable")]
    bounds = np.searchsorted(owner[srt], np.arange(C + 1))
    out = []
    for k in range(C):
        members = srt[bounds[k] : bounds[k + 1]]
        if len(members) >= config.min_plane_points:
            out.append(np.sort(members))
    return out
