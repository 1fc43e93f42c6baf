"""What was seen of a plane: its support polygon and its majority true label."""

from __future__ import annotations

import numba
import numpy as np

#: Directions in which support_polygon takes the extreme point (every 360 / 32 deg).
_POLY_DIRS = np.stack(
    [np.cos(np.arange(32) * np.pi / 16), np.sin(np.arange(32) * np.pi / 16)], axis=0
)


def support_polygon(points: np.ndarray, centroid: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """(M, 3) convex polygon of ``points`` (K, 3) (the inliers) projected on the plane
    through ``centroid`` (3,) spanned by the unit ``axes`` (3, 2) (the in-plane
    eigenvectors e1, e2 of the fit), in order.

    The polygon joins the extreme points of the projected inliers in 32 directions, 11.25
    deg apart, counter-clockwise about e1 x e2: each vertex is a
    vertex of the convex hull, and the polygon differs from the hull only by hull
    vertices between two sampled directions (a few cm on a wall). qhull (scipy) gives the
    exact hull but costs ~0.1 ms per call, more than the rest of a plane's fit; this runs
    compiled (numba) in one pass over the points. (0, 3) when the points are degenerate.
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    if len(pts) < 3:
        return np.zeros((0, 3))
    basis = np.ascontiguousarray(axes)
    return _polygon_kernel(pts, np.ascontiguousarray(centroid), basis, _POLY_DIRS)


@numba.njit(cache=True)
def _polygon_kernel(points, centroid, basis, dirs):  # pragma: no cover - compiled
    K = points.shape[0]
    D = dirs.shape[1]
    u = np.empty(K)
    v = np.empty(K)
    for i in range(K):
        q0, q1, q2 = (
            points[i, 0] - centroid[0],
            points[i, 1] - centroid[1],
            points[i, 2] - centroid[2],
        )
        u[i] = q0 * basis[0, 0] + q1 * basis[1, 0] + q2 * basis[2, 0]
        v[i] = q0 * basis[0, 1] + q1 * basis[1, 1] + q2 * basis[2, 1]
    arg = np.empty(D, dtype=np.int64)
    for k in range(D):
        best = -np.inf
        for i in range(K):  # the first maximum, as np.argmax
            h = u[i] * dirs[0, k] + v[i] * dirs[1, k]
            if h > best:
                best = h
                arg[k] = i
    keep = np.ones(D, dtype=np.bool_)
    for k in range(1, D):
        keep[k] = arg[k] != arg[k - 1]
    if arg[D - 1] == arg[0] and keep.sum() > 1:
        keep[D - 1] = False
    sel = arg[keep]
    M = sel.shape[0]
    if M < 3:
        return np.zeros((0, 3))
    mu = 0.0
    mv = 0.0
    for k in range(M):
        mu += u[sel[k]]
        mv += v[sel[k]]
    mu /= M
    mv /= M
    area2 = 0.0
    emax = 0.0
    for k in range(M):
        e0, e1 = u[sel[k]] - mu, v[sel[k]] - mv
        f0, f1 = u[sel[(k + 1) % M]] - mu, v[sel[(k + 1) % M]] - mv
        area2 += e0 * f1 - f0 * e1
        emax = max(emax, abs(e0), abs(e1))
    if not abs(area2) > 1e-12 * max(emax * emax, 1e-300):
        return np.zeros((0, 3))
    out = np.empty((M, 3))
    for k in range(M):
        for c in range(3):
            out[k, c] = centroid[c] + u[sel[k]] * basis[c, 0] + v[sel[k]] * basis[c, 1]
    return out


def support_polygons(
    points: np.ndarray,
    inliers: np.ndarray,
    bounds: np.ndarray,
    outline: np.ndarray,
    planes: np.ndarray,
    centroids: np.ndarray,
    evecs: np.ndarray,
) -> list[np.ndarray]:
    """:func:`support_polygon` of each plane g in ``planes`` (P,) at once: of its outline
    points ``points[inliers[k]]`` ((N, 3) m) for k in ``bounds[g]:bounds[g + 1]`` where
    ``outline[k]`` ((K,) int64, (G + 1,) int64, (K,) bool), about ``centroids[g]`` (G, 3)
    in the plane of the first two columns of ``evecs[g]`` (G, 3, 3). One compiled pass (a
    numpy gather and three conversions per plane cost more than the polygon)."""
    flat, vb = _polygons_kernel(
        np.ascontiguousarray(points, dtype=np.float64), inliers.astype(np.int64),
        bounds.astype(np.int64), outline, np.asarray(planes, dtype=np.int64),
        np.ascontiguousarray(centroids, dtype=np.float64),
        np.ascontiguousarray(evecs[:, :, :2], dtype=np.float64), _POLY_DIRS,
    )  # fmt: skip
    return [flat[vb[p] : vb[p + 1]].copy() for p in range(len(planes))]


@numba.njit(cache=True)
def _polygons_kernel(pts, inliers, bounds, outline, planes, cen, axes, dirs):  # pragma: no cover
    """The polygons of :func:`support_polygons`, stacked, and (P + 1,) their bounds."""
    P = planes.shape[0]
    D = dirs.shape[1]
    out = np.empty((P * D, 3))
    vb = np.zeros(P + 1, dtype=np.int64)
    for p in range(P):
        g = planes[p]
        a, b = bounds[g], bounds[g + 1]
        buf = np.empty((b - a, 3))
        n = 0
        for k in range(a, b):
            if outline[k]:
                i = inliers[k]
                buf[n, 0], buf[n, 1], buf[n, 2] = pts[i, 0], pts[i, 1], pts[i, 2]
                n += 1
        m = 0
        if n >= 3:
            poly = _polygon_kernel(buf[:n], cen[g].copy(), axes[g].copy(), dirs)
            m = poly.shape[0]
            out[vb[p] : vb[p] + m] = poly
        vb[p + 1] = vb[p] + m
    return out[: vb[P]].copy(), vb


def majority_label(labels: np.ndarray | None) -> int:
    """Most frequent non-negative label among ``labels`` (K,), or -1."""
    if labels is None or len(labels) == 0:
        return -1
    lab = labels[labels >= 0]
    if len(lab) == 0:
        return -1
    if lab.max() < 1_000_000:  # small ids (every simulated scene): one counting pass
        return int(np.argmax(np.bincount(lab)))
    values, counts = np.unique(lab, return_counts=True)
    return int(values[np.argmax(counts)])


def distinct_and_majority(
    ring: np.ndarray | None,
    labels: np.ndarray | None,
    inliers: np.ndarray,
    bounds: np.ndarray,
    planes: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Per plane g in ``planes`` (P,): the number of distinct ``ring`` values (0 without
    rings) and :func:`majority_label` of ``labels`` (-1 without) over its inliers
    ``inliers[bounds[g]:bounds[g + 1]]`` (scan indices), in one compiled pass (two numpy
    gathers and counts per plane cost a tenth of a 2D-rig extraction). Returns (P,) int64
    arrays."""
    empty = np.zeros(0, dtype=np.int64)
    return _distinct_majority_kernel(
        empty if ring is None else ring, empty if labels is None else labels,
        inliers.astype(np.int64), bounds.astype(np.int64), planes.astype(np.int64),
        ring is not None, labels is not None,
    )  # fmt: skip


@numba.njit(cache=True)
def _distinct_majority_kernel(
    ring, labels, inliers, bounds, planes, has_ring, has_labels
):  # pragma: no cover
    P = len(planes)
    n_rows = np.zeros(P, dtype=np.int64)
    truth = np.full(P, -1, dtype=np.int64)
    for p in range(P):
        a, b = bounds[planes[p]], bounds[planes[p] + 1]
        if has_ring and b > a:
            counts = _counts(ring, inliers, a, b, False)
            n_rows[p] = np.count_nonzero(counts[1]) if counts[0] else len(np.unique(counts[1]))
        if has_labels and b > a:
            counts = _counts(labels, inliers, a, b, True)
            if counts[0]:  # the smallest of the most frequent non-negative labels
                if len(counts[1]) and counts[1].max() > 0:
                    truth[p] = np.argmax(counts[1])
            else:
                vals = np.sort(counts[1])
                best, best_n, run = -1, 0, 0
                for k in range(len(vals)):
                    run = run + 1 if k > 0 and vals[k] == vals[k - 1] else 1
                    if run > best_n:
                        best, best_n = vals[k], run
                truth[p] = best
    return n_rows, truth


@numba.njit(cache=True)
def _counts(values, inliers, a, b, skip_negative):  # pragma: no cover - compiled
    """``(True, counts)``: how often each small non-negative id (below 2^20) occurs among
    ``values[inliers[a:b]]`` (negative ones ignored with ``skip_negative``); else
    ``(False, ids)``: the ids themselves (the non-negative ones with ``skip_negative``)."""
    hi, lo = -1, 0
    for k in range(a, b):
        hi = max(hi, values[inliers[k]])
        lo = min(lo, values[inliers[k]])
    if hi < 1 << 20 and (lo >= 0 or skip_negative):
        counts = np.zeros(hi + 1, dtype=np.int64)
        for k in range(a, b):
            v = values[inliers[k]]
            if v >= 0:
                counts[v] += 1
        return True, counts
    ids = np.empty(b - a, dtype=np.int64)
    m = 0
    for k in range(a, b):
        if values[inliers[k]] >= 0 or not skip_negative:
            ids[m] = values[inliers[k]]
            m += 1
    return False, ids[:m].copy()
