"""Robust total-least-squares plane fits, their covariance, orientation and support.

Covariance of a TLS plane fit (first order, isotropic point noise sigma along n):

Let ``c`` be the centroid of the N inliers, ``C = sum (p - c)(p - c)^T`` their scatter with
eigenvalues ``l1 >= l2 >= l3`` and eigenvectors ``e1, e2, e3 = n``. A perturbation ``dC``
moves the smallest eigenvector by ``dn = -sum_k e_k (e_k^T dC n) / (l_k - l3)``, k = 1, 2.
With point noise ``eps_i`` (sigma along n) ``e_k^T dC n = sum_i (e_k . (p_i - c)) (n . eps_i)``
plus a second-order term, of variance ``sigma^2 (l_k^true + N sigma^2) ~ sigma^2 l_k``; the
two are uncorrelated (e1, e2 diagonalise C). Hence

    Cov(n) = sigma^2 sum_{k=1,2} l_k / (l_k - l3)^2 e_k e_k^T      (rank 2, nothing along n)

``d = -n . c`` gives ``dd = -c . dn - n . dc`` with ``Var(n . dc) = sigma^2 / N``,
uncorrelated with ``dn`` (centred sums), so

    Cov(n, d) = -Cov(n) c,    Var(d) = c^T Cov(n) c + sigma^2 / N.

``sigma^2`` is estimated by the residual variance ``l3 / (N - 3)`` (three parameters fitted),
bounded below by ``covariance_sigma_floor_m^2``. The 4x4 covariance of ``(n, d)`` has rank 3.
It does not change when the plane is flipped (``(n, d) -> (-n, -d)``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from planodom.geometry import PlaneSupport

#: Residuals below this (m) always count as inliers (round-off of exact data).
_EXACT_M = 1e-7


@dataclass(frozen=True, eq=False)
class PlaneFit:
    """A TLS fit to inlier points.

    Attributes:
        inliers: (K,) int64 indices of the inliers among the fitted points.
        normal: (3,) unit normal (not yet oriented). offset: d, metres.
        centroid: (3,) metres. evals: (3,) scatter eigenvalues, descending, m^2.
        evecs: (3, 3) columns e1, e2, n.
    """

    inliers: np.ndarray
    normal: np.ndarray
    offset: float
    centroid: np.ndarray
    evals: np.ndarray
    evecs: np.ndarray

    @property
    def n_points(self) -> int:
        return len(self.inliers)

    @property
    def rms(self) -> float:
        """RMS residual (m) of the inliers."""
        return float(np.sqrt(max(self.evals[2], 0.0) / max(len(self.inliers), 1)))

    @property
    def width(self) -> float:
        """In-plane width (m) along the minor axis: ``2 sqrt(l2 / N)``."""
        return float(2.0 * np.sqrt(max(self.evals[1], 0.0) / max(len(self.inliers), 1)))


def tls_fit(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centroid (3,), eigenvalues (3,) descending and eigenvectors (3, 3) of the scatter."""
    c = points.mean(axis=0)
    q = points - c
    evals, evecs = np.linalg.eigh(q.T @ q)
    return c, evals[::-1], evecs[:, ::-1]


def robust_plane_fit(points: np.ndarray, k_sigma: float, max_iter: int = 4) -> PlaneFit | None:
    """TLS plane through ``points`` (N, 3), metres, with iterated robust inlier selection.

    Residuals ``r`` to the current fit are kept when ``|r| <= max(k_sigma * 1.4826 *
    median(|r|), 1e-7 m)``; the fit is redone on the inliers until they stop changing.
    Returns None when fewer than 3 points remain.
    """
    idx = np.arange(len(points))
    for _ in range(max_iter):
        if len(idx) < 3:
            return None
        c, evals, evecs = tls_fit(points[idx])
        n = evecs[:, 2]
        r = np.abs((points - c) @ n)
        thr = max(k_sigma * 1.4826 * float(np.median(r[idx])), _EXACT_M)
        new = np.flatnonzero(r <= thr)
        if np.array_equal(new, idx):
            break
        idx = new
    if len(idx) < 3:
        return None
    c, evals, evecs = tls_fit(points[idx])
    n = evecs[:, 2]
    return PlaneFit(idx, n, float(-n @ c), c, evals, evecs)


def tls_covariance(fit: PlaneFit, sigma_floor_m: float) -> np.ndarray:
    """(4, 4) covariance of ``(nx, ny, nz, d)`` of a TLS fit (module docstring)."""
    return tls_covariances(
        fit.evals[None], fit.evecs[None], fit.centroid[None], np.array([fit.n_points]),
        sigma_floor_m,
    )[0]  # fmt: skip


def tls_covariances(
    evals: np.ndarray,
    evecs: np.ndarray,
    centroids: np.ndarray,
    n_points: np.ndarray,
    sigma_floor_m: float,
) -> np.ndarray:
    """(G, 4, 4) covariances of G TLS fits at once (module docstring).

    Args:
        evals: (G, 3) scatter eigenvalues, descending (m^2). evecs: (G, 3, 3) columns
        e1, e2, n. centroids: (G, 3) metres. n_points: (G,) inlier counts.
        sigma_floor_m: lower bound of the residual sigma (m).
    """
    n_pts = np.asarray(n_points, dtype=np.float64)
    l1, l2, l3 = evals[:, 0], evals[:, 1], evals[:, 2]
    sigma2 = np.maximum(l3 / np.maximum(n_pts - 3.0, 1.0), sigma_floor_m**2)
    w = sigma2[:, None] * np.stack([l1 / (l1 - l3) ** 2, l2 / (l2 - l3) ** 2], axis=1)
    e12 = evecs[:, :, :2]
    cov_n = np.einsum("gik,gk,gjk->gij", e12, w, e12)
    cn = np.einsum("gij,gj->gi", cov_n, centroids)
    cov = np.empty((len(n_pts), 4, 4))
    cov[:, :3, :3] = cov_n
    cov[:, :3, 3] = -cn
    cov[:, 3, :3] = -cn
    cov[:, 3, 3] = np.einsum("gi,gi->g", centroids, cn) + sigma2 / n_pts
    return cov


def orientation_sign(
    normal: np.ndarray,
    offset: float,
    centroid: np.ndarray,
    viewpoint: np.ndarray,
) -> float:
    """+1 or -1: the sign that makes the normal point towards the side the sensor saw from.

    The plane is oriented so that ``viewpoint`` (3,) (the mean sensor origin of the
    inliers when known, else a point above the base origin) lies on its positive side. If
    the viewpoint lies on the plane (|distance| < 1 mm) a near-horizontal plane
    (|n_z| >= cos 45 deg) gets its normal up, any other its normal towards the base
    origin's side of the centroid.
    """
    return float(
        orientation_signs(normal[None], np.array([offset]), centroid[None], viewpoint[None])[0]
    )


def orientation_signs(
    normals: np.ndarray, offsets: np.ndarray, centroids: np.ndarray, viewpoints: np.ndarray
) -> np.ndarray:
    """(G,) :func:`orientation_sign` of G planes: normals (G, 3), offsets (G,), centroids
    (G, 3) and viewpoints (G, 3) (or (3,) for all), metres."""
    views = np.broadcast_to(viewpoints, normals.shape)
    dist = np.einsum("gi,gi->g", normals, views) + offsets
    up = np.where(normals[:, 2] > 0, 1.0, -1.0)
    towards = -np.einsum("gi,gi->g", normals[:, :2], centroids[:, :2])
    side = np.where(towards < 0, -1.0, 1.0)
    on_plane = np.where(np.abs(normals[:, 2]) >= np.cos(np.radians(45.0)), up, side)
    return np.where(np.abs(dist) >= 1e-3, np.where(dist > 0, 1.0, -1.0), on_plane)


#: Directions in which support_polygon takes the extreme point (every 360 / 32 deg).
_POLY_DIRS = np.stack(
    [np.cos(np.arange(32) * np.pi / 16), np.sin(np.arange(32) * np.pi / 16)], axis=0
)


def support_polygon(points: np.ndarray, fit: PlaneFit) -> np.ndarray:
    """(M, 3) convex polygon of ``points`` (the inliers) projected on the plane, in order.

    The polygon joins the extreme points of the projected inliers in 32 directions, 11.25
    deg apart, counter-clockwise about the (unoriented) fit normal: each vertex is a
    vertex of the convex hull, and the polygon differs from the hull only by hull
    vertices between two sampled directions (a few cm on a wall). qhull (scipy) gives the
    exact hull but costs ~0.1 ms per call, more than the rest of a plane's fit; this runs
    compiled (numba) in one pass over the points. (0, 3) when the points are degenerate.
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    if len(pts) < 3:
        return np.zeros((0, 3))
    basis = np.ascontiguousarray(fit.evecs[:, :2])
    return _polygon_kernel(pts, np.ascontiguousarray(fit.centroid), basis, _POLY_DIRS)


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


def make_support(points: np.ndarray, fit: PlaneFit) -> PlaneSupport:
    """:class:`PlaneSupport` of the inlier ``points`` (K, 3) of ``fit``."""
    return PlaneSupport(fit.centroid.copy(), support_polygon(points, fit), fit.n_points)


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
