"""Robust total-least-squares plane fits and their covariance.

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

from planodom.extraction.kernels import add_outer

#: Residuals below this (m) always count as inliers (round-off of exact data).
_EXACT_M = 1e-7


@dataclass(frozen=True, eq=False)
class PlaneFit:
    """A TLS fit to inlier points (:func:`robust_plane_fit`).

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


def tls_fit(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centroid (3,), eigenvalues (3,) descending and eigenvectors (3, 3) of the scatter."""
    # the sum that ndarray.mean takes (the same bits) without its wrapper's overhead: tens
    # of thousands of small fits per lidar run
    c = np.add.reduce(points, axis=0) / len(points)
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


def robust_plane_fits(
    points: np.ndarray, bounds: np.ndarray, k_sigma: float, max_iter: int = 4
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`robust_plane_fit` of G point sets in one compiled loop (the same iterations,
    results equal to rounding): set g is ``points[bounds[g]:bounds[g + 1]]``.

    One numpy fit per candidate was a large share of a lidar epoch's extraction (tens of
    candidates, each a dozen small numpy calls per iteration); a numpy version over all
    points at once was slower still (every iteration passes over every point of every
    set, where most sets stop after one or two), hence a numba kernel.

    Args:
        points: (M, 3) metres, the sets one after another. bounds: (G + 1,) int64.
        k_sigma, max_iter: as :func:`robust_plane_fit`.

    Returns:
        ``inlier`` (M,) bool (False throughout a failed set), ``ok`` (G,) bool (False:
        fewer than 3 inliers remained), and per set the centroid (G, 3), eigenvalues
        (G, 3) descending and eigenvectors (G, 3, 3) of the final fit (zeros where not ok).
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    b = np.ascontiguousarray(bounds, dtype=np.int64)
    n_sets = len(b) - 1
    inlier = np.zeros(len(pts), dtype=np.bool_)
    ok = np.zeros(n_sets, dtype=np.bool_)
    c = np.zeros((n_sets, 3))
    evals = np.zeros((n_sets, 3))
    evecs = np.zeros((n_sets, 3, 3))
    _robust_fits_kernel(pts, b, float(k_sigma), int(max_iter), inlier, ok, c, evals, evecs)
    return inlier, ok, c, evals, evecs


@numba.njit(cache=True)
def _tls_kernel(p: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`tls_fit` of ``p[idx]``: centroid, eigenvalues descending, eigenvectors."""
    c = np.zeros(3)
    for i in idx:
        for a in range(3):
            c[a] += p[i, a]
    c /= len(idx)
    S = np.zeros((3, 3))
    for i in idx:
        add_outer(S, p[i, 0] - c[0], p[i, 1] - c[1], p[i, 2] - c[2])
    S[1, 0], S[2, 0], S[2, 1] = S[0, 1], S[0, 2], S[1, 2]
    w, V = np.linalg.eigh(S)
    return c, w[::-1].copy(), V[:, ::-1].copy()


@numba.njit(cache=True)
def _robust_fits_kernel(points, bounds, k_sigma, max_iter, inlier, ok, c_out, e_out, v_out):
    for g in range(len(bounds) - 1):
        p = points[bounds[g] : bounds[g + 1]]
        idx = np.arange(len(p))
        failed = False
        converged = False  # the last fit is of the final inliers: not fitted again
        c, w, V = np.zeros(3), np.zeros(3), np.zeros((3, 3))
        for _ in range(max_iter):
            if len(idx) < 3:
                failed = True
                break
            c, w, V = _tls_kernel(p, idx)
            r = np.empty(len(p))
            for i in range(len(p)):
                r[i] = abs(
                    (p[i, 0] - c[0]) * V[0, 2]
                    + (p[i, 1] - c[1]) * V[1, 2]
                    + (p[i, 2] - c[2]) * V[2, 2]
                )
            thr = max(k_sigma * 1.4826 * np.median(r[idx]), _EXACT_M)
            new = np.flatnonzero(r <= thr)
            if len(new) == len(idx) and np.all(new == idx):
                converged = True
                break
            idx = new
        if failed or len(idx) < 3:
            continue
        if not converged:
            c, w, V = _tls_kernel(p, idx)
        ok[g] = True
        c_out[g], e_out[g], v_out[g] = c, w, V
        for j in idx:
            inlier[bounds[g] + j] = True


def tls_covariance(
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


@numba.njit(cache=True)
def _nan_max(a, b):  # pragma: no cover - compiled
    """``np.maximum`` of two floats (NaN when either is)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a >= b else b


@numba.njit(cache=True, error_model="numpy")  # 0 / 0 is NaN, as in numpy
def fit_arrays(  # pragma: no cover - compiled
    evals, evecs, centroids, n_points, floor2, min_points, min_width, max_var_n
):
    """:func:`tls_covariance` and the builder's per-fit arrays of G fits in one compiled
    pass (the numpy form is ~25 calls on a handful of fits, per extraction): covariances
    (G, 4, 4); widths ``2 sqrt(l2 / N)`` and RMS ``sqrt(l3 / N)`` (G,) (N at least 1);
    whether each passes the plane tests (``min_points``, ``min_width`` m, the trace of
    the normal's covariance at most ``max_var_n`` rad^2); the scatters (G, 3, 3) ``V diag(l)
    V^T``. ``floor2`` is the squared sigma floor (m^2). The same operations in the same
    order as the numpy form, so the same bits: einsum sums the products over a strided
    axis from the first on, and the three of two contiguous rows as (first + third) +
    second (two SIMD lanes; checked against numpy in the tests)."""
    G = evals.shape[0]
    covs = np.empty((G, 4, 4))
    width = np.empty(G)
    rms = np.empty(G)
    keep = np.zeros(G, dtype=np.bool_)
    scatter = np.empty((G, 3, 3))
    w = np.empty(2)
    cn = np.empty(3)
    for g in range(G):
        n = float(n_points[g])
        cnt = _nan_max(n, 1.0)
        l1, l2, l3 = evals[g, 0], evals[g, 1], evals[g, 2]
        width[g] = 2.0 * np.sqrt(_nan_max(l2, 0.0) / cnt)
        rms[g] = np.sqrt(_nan_max(l3, 0.0) / cnt)
        sigma2 = _nan_max(l3 / _nan_max(n - 3.0, 1.0), floor2)
        w[0] = sigma2 * (l1 / ((l1 - l3) * (l1 - l3)))
        w[1] = sigma2 * (l2 / ((l2 - l3) * (l2 - l3)))
        for i in range(3):
            for j in range(3):
                acc = 0.0
                for k in range(2):
                    acc += evecs[g, i, k] * w[k] * evecs[g, j, k]
                covs[g, i, j] = acc
                acc = 0.0
                for k in range(3):
                    acc += evecs[g, i, k] * evals[g, k] * evecs[g, j, k]
                scatter[g, i, j] = acc
        c0, c1, c2 = centroids[g, 0], centroids[g, 1], centroids[g, 2]
        for i in range(3):  # numpy's einsum order on contiguous rows: (0 + 2) + 1
            cn[i] = (covs[g, i, 0] * c0 + covs[g, i, 2] * c2) + covs[g, i, 1] * c1
        dd = (c0 * cn[0] + c2 * cn[2]) + c1 * cn[1]
        for i in range(3):
            covs[g, i, 3] = -cn[i]
            covs[g, 3, i] = -cn[i]
        covs[g, 3, 3] = dd + sigma2 / n
        var_n = covs[g, 0, 0] + covs[g, 1, 1] + covs[g, 2, 2]
        keep[g] = n_points[g] >= min_points and width[g] >= min_width and not var_n > max_var_n
    return covs, width, rms, keep, scatter


def deskew_jacobian(
    points: np.ndarray,
    t: np.ndarray,
    normal: np.ndarray,
    fit: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """(4, 6) first-order change of a TLS plane fit's ``(n, d)`` (as its covariance) when
    its points are deskewed with a twist off by ``dxi = (dw, dv)`` (rad and m per unit of
    ``t``).

    A point seen ``t_i`` after the reference time moves by ``t_i (dw x p_i + dv)``, i.e.
    along the normal by ``g_i . dxi`` with ``g_i = t_i (p_i x n, n)``. With the scatter's
    eigen-decomposition (module docstring, ``l3`` the plane's own) the normal moves by
    ``dn = -sum_{k=1,2} e_k sum_i (e_k . q_i) (g_i . dxi) / (l_k - l3)`` (``q_i = p_i - c``)
    and ``d = -n . c`` by ``-c . dn - mean_i (g_i . dxi)``. Unlike a rigid perturbation of
    the epoch's frame, this holds where along the plane, and when, its points were seen:
    a wall swept over the epoch is tilted by a wrong rate, a plane seen at the start of
    the epoch hardly moves.

    Args:
        points: (K, 3) the inliers as fitted (deskewed), metres. t: (K,) their times
            relative to the reference time. normal: (3,) the fit's unit normal (oriented).
        basis: (3, 2) orthonormal tangent basis of the normal (``gtsam.Unit3.basis``).
    """
    c, evals, evecs = tls_fit(points) if fit is None else fit
    q = points - c
    # sums of w_i g_i for the weights w_i = 1, e1 . q_i, e2 . q_i from the moments
    # sum w t and sum w t p (3 x 3), not g_i point by point
    w = np.empty((len(points), 3))
    w[:, 0] = 1.0
    w[:, 1:] = q @ evecs[:, :2]
    w *= t[:, None]
    m = w.T @ points
    sums = np.empty((3, 6))  # [m x n, (sum w) n], the cross product written out (as numpy's)
    sums[:, 0] = m[:, 1] * normal[2] - m[:, 2] * normal[1]
    sums[:, 1] = m[:, 2] * normal[0] - m[:, 0] * normal[2]
    sums[:, 2] = m[:, 0] * normal[1] - m[:, 1] * normal[0]
    sums[:, 3:] = w.sum(axis=0)[:, None] * normal
    out = np.zeros((4, 6))
    dn = out[:3]
    dn -= (evecs[:, 0, None] * sums[1]) / max(float(evals[0] - evals[2]), 1e-300)
    dn -= (evecs[:, 1, None] * sums[2]) / max(float(evals[1] - evals[2]), 1e-300)
    out[3] = -(c @ dn) - sums[0] / len(points)
    return out
