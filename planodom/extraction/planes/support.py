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
