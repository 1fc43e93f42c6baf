"""Continuous-time registration: a scan's own twist measured against the plane map
(``planemap.twist_estimation``).

A scan's points are deskewed to its reference time with a twist ``xi`` predicted from the
steps before it (:mod:`planodom.odometry.deskew`). If the true twist over the sweep is
``xi + (dw, dv)`` (and, with ``registered_acceleration``, changes at ``(aw, av)`` per
second), a point ``p_i`` seen ``t_i`` after the reference time truly lies, to first order
in the correction, at ``p_i + t_i (dw x p_i + dv) + t_i^2 / 2 (aw x p_i + av)``. Its
distance to a map plane ``(n, d)`` under the pose ``(R, t)`` (world from scan), with
``u = R^T n``, ``e = n . t + d`` and ``h_i = (p_i - c, 1)`` (``c`` the plane's centroid),
is ``z_0 . h_i + t_i z_1 . h_i + t_i^2 z_2 . h_i`` with::

    z_0 = (u, u . c + e)
    z_1 = (u x dw, (u x dw) . c + u . dv)
    z_2 = (u x aw, (u x aw) . c + u . av) / 2

so the exact sum of squares over the plane's points is ``sum_kl z_k^T M_(k+l) z_l``, with
the plane's time moments ``M_k = sum t_i^k h_i h_i^T`` (k = 0..4,
``PlaneSupport.time_moments``): O(planes) per iteration, as the pose-only moments
(:mod:`.moments`; with ``dw = dv = 0`` it is their cost). Factoring the (8, 8) or (12, 12)
block matrix ``Q = V diag(l) V^T`` gives residuals ``diag(sqrt l) V^T z`` whose sum of
squares is that cost; Gauss-Newton solves the pose (``R <- exp(w) R, t <- t + dt``, as
:mod:`.register`) and the twist correction together over the registration's inlier
associations, each whitened by one variance (the mean of its offset and tilt residuals'
variances, landmark uncertainty included, times the scan's residual scale, over its
Cauchy weight), with a zero-mean prior on the correction (the twist prediction's
uncertainty, :meth:`PlaneMapOdometry._twist_prior`). A direction of the solve without
information keeps its value (the eigenvalue cut of :mod:`.register`).

The first-order model neglects terms of ``t_i^2 |w| |dw|`` (the twist's own rotation
over the sweep times the correction); the odometry extracts the epoch again with the
corrected twist (:func:`planodom.odometry.deskew.register_deskewed`), and the next
registration measures what is left.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planodom.median import median
from planodom.odometry.planemap.landmarks import PlaneMap
from planodom.odometry.planemap.moments import Moments
from planodom.odometry.planemap.outliers import TESTED, residual_scale, whitened
from planodom.odometry.planemap.register import Registration, ScanPlanes, newton_step
from planodom.rotvec import rotation_matrices


@dataclass(frozen=True, eq=False)
class TwistRegistration:
    """The pose and the twist correction of a scan registered in continuous time.

    Attributes:
        T: (4, 4) world from scan at the reference time.
        correction: (6,) ``(dw, dv)`` rad/s, m/s to add to the twist the scan was
            deskewed with (body frame at the reference time).
        acceleration: (6,) ``(aw, av)`` rad/s^2, m/s^2 (zeros unless estimated).
        H: (n, n) information of (rotation, translation, dw, dv[, aw, av]) at the
            solution (prior included).
    """

    T: np.ndarray
    correction: np.ndarray
    acceleration: np.ndarray
    H: np.ndarray


def _skew(a: np.ndarray) -> np.ndarray:
    """(..., 3, 3) cross-product matrices of (..., 3) vectors."""
    S = np.zeros((*a.shape[:-1], 3, 3))
    S[..., 0, 1], S[..., 0, 2] = -a[..., 2], a[..., 1]
    S[..., 1, 0], S[..., 1, 2] = a[..., 2], -a[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -a[..., 1], a[..., 0]
    return S


def block_moments(moments: np.ndarray, order: int) -> np.ndarray:
    """(m, 4 (order + 1), 4 (order + 1)) ``Q`` of time moments (m, 5, 4, 4): block
    ``(k, l)`` is ``M_(k+l)``; ``order`` 1 (constant twist) or 2 (with acceleration)."""
    q = order + 1
    Q = np.zeros((len(moments), 4 * q, 4 * q))
    for k in range(q):
        for l in range(q):
            Q[:, 4 * k : 4 * k + 4, 4 * l : 4 * l + 4] = moments[:, k + l]
    return Q


def stacked(
    R: np.ndarray, t: np.ndarray, n: np.ndarray, d: np.ndarray, c: np.ndarray, x: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``z`` (m, 4 q) of m planes (module docstring) and its Jacobian (m, 4 q, 6 q) in
    (rotation, translation, dw, dv[, aw, av]); ``x`` (6 (q - 1),) the twist correction
    (and acceleration), ``n`` (m, 3), ``d`` (m,) the map planes (world), ``c`` (m, 3)
    the scan planes' centroids (scan frame)."""
    q = 1 + len(x) // 6
    m = len(d)
    u = n @ R  # rows R^T n
    e = n @ t + d
    A = np.einsum("ba,mbc->mac", R, _skew(n))  # du/dphi = R^T [n]x
    z = np.zeros((m, 4 * q))
    J = np.zeros((m, 4 * q, 6 * q))
    z[:, :3] = u
    z[:, 3] = np.einsum("mi,mi->m", u, c) + e
    J[:, :3, :3] = A
    J[:, 3, :3] = np.einsum("mi,mij->mj", c, A)
    J[:, 3, 3:6] = n
    for k in range(1, q):
        f = 0.5 if k == 2 else 1.0
        w, v = x[6 * (k - 1) : 6 * (k - 1) + 3], x[6 * (k - 1) + 3 : 6 * k]
        uw = np.cross(u, w)
        rows = slice(4 * k, 4 * k + 3)
        cols_w, cols_v = slice(6 * k, 6 * k + 3), slice(6 * k + 3, 6 * k + 6)
        z[:, rows] = f * uw
        z[:, 4 * k + 3] = f * (np.einsum("mi,mi->m", uw, c) + u @ v)
        dw_du = -_skew(w)  # d(u x w)/du
        J[:, rows, :3] = f * np.einsum("ij,mjk->mik", dw_du, A)
        J[:, rows, cols_w] = f * _skew(u)
        J[:, 4 * k + 3, :3] = f * np.einsum("mi,mik->mk", c @ dw_du + v, A)
        J[:, 4 * k + 3, cols_w] = f * np.einsum("mi,mij->mj", c, _skew(u))
        J[:, 4 * k + 3, cols_v] = f * u
    return z, J


def corrected_moments(
    c: np.ndarray, moments: np.ndarray, x: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Count (m,), centroid (m, 3) and centred scatter (m, 3, 3) of m planes' points
    moved by the twist correction ``x`` (6 or 12,) (``p + t (dw x p + dv) [+ t^2 / 2 (aw
    x p + av)]``), from their centroids ``c`` (m, 3) and time moments (m, 5, 4, 4):
    ``h' = sum_k t^k G_k h`` with ``G_0 = I``, ``G_k = [[f [w]x, f ([w]x c + v)], [0,
    0]]``, so ``sum h' h'^T = sum_kl G_k M_(k+l) G_l^T``."""
    q = 1 + len(x) // 6
    m = len(c)
    G = np.zeros((q, m, 4, 4))
    G[0] = np.eye(4)
    for k in range(1, q):
        f = 0.5 if k == 2 else 1.0
        w, v = x[6 * (k - 1) : 6 * (k - 1) + 3], x[6 * (k - 1) + 3 : 6 * k]
        G[k, :, :3, :3] = f * _skew(w)
        G[k, :, :3, 3] = f * (c @ _skew(w).T + v)
    H = np.zeros((m, 4, 4))
    for k in range(q):
        for l in range(q):
            H += G[k] @ moments[:, k + l] @ np.swapaxes(G[l], 1, 2)
    N = H[:, 3, 3]
    mean = H[:, :3, 3] / N[:, None]
    S = H[:, :3, :3] - N[:, None, None] * mean[:, :, None] * mean[:, None, :]
    return N, c + mean, S


def ct_cost(
    R: np.ndarray,
    t: np.ndarray,
    n: np.ndarray,
    d: float,
    c: np.ndarray,
    moments: np.ndarray,
    x: np.ndarray,
) -> float:
    """The sum of squared point-to-plane distances of one plane's points (centroid ``c``
    (3,), time moments (5, 4, 4)) moved by the twist correction ``x`` (6 or 12,) and the
    pose (R, t) from the moments (module docstring)."""
    q = 1 + len(x) // 6
    z, _ = stacked(R, t, n[None], np.array([d]), c[None], x)
    return float(z[0] @ block_moments(moments[None], q - 1)[0] @ z[0])


def register_twist(
    M: PlaneMap,
    reg: Registration,
    cur: ScanPlanes,
    moments: np.ndarray,
    prior_sd: np.ndarray,
    iterations: int,
    rounds: int = 2,
    prior: tuple[np.ndarray, np.ndarray] | None = None,
) -> TwistRegistration | None:
    """The pose and twist correction of the scan (module docstring) from the
    registration ``reg`` (its inlier associations, weights and pose), the scan planes
    ``cur`` and their time moments (K, 5, 4, 4); ``prior_sd`` (6,) or (12,) the prior
    sigma of the correction (and acceleration) per axis. ``rounds``: solves, each with
    the residual scale of the planes as the last one corrected them (a scan deskewed far
    off disagrees with the map by far more than its noise until corrected: with the scale
    of its uncorrected planes the prior would hold the correction back). ``prior``:
    (mean (n,), information (n, n)) of the correction instead (``planemap.twist_filter``:
    the filter's prediction, :mod:`.twist_filter`), n = len(prior_sd). None without 3
    inliers."""
    keep = reg.weights > 0.5
    if np.count_nonzero(keep) < 3:
        return None
    lm, jj, w = reg.landmarks[keep], reg.planes[keep], reg.weights[keep]
    c = cur.m.c[jj]
    order = len(prior_sd) // 6
    if prior is None:
        prior = (np.zeros(6 * order), np.diag(1.0 / prior_sd**2))
    x = np.zeros(6 * order)
    T, H = reg.T, np.eye(6 * (order + 1))
    for _ in range(rounds):
        # the scan's residual scale and the variances at the corrected planes
        Nx, cx, Sx = corrected_moments(c, moments[jj], x)
        lam, E = np.linalg.eigh(Sx)
        _, _, v, chi2 = whitened(M, T[:3, :3], T[:3, 3], Nx, cx, lam, E, cur.variances(jj), lm)
        var = residual_scale(chi2) * v[:, TESTED].mean(axis=1) / w
        T, x, H = _solve(M, T, lm, c, moments[jj], var, x, prior, iterations)
    acc = x[6:12] if order == 2 else np.zeros(6)
    return TwistRegistration(T, x[:6].copy(), acc.copy(), H)


def _solve(
    M: PlaneMap,
    T0: np.ndarray,
    lm: np.ndarray,
    c: np.ndarray,
    moments: np.ndarray,
    var: np.ndarray,
    x: np.ndarray,
    prior: tuple[np.ndarray, np.ndarray],
    iterations: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gauss-Newton of the pose and the correction from ``T0`` and ``x`` (module
    docstring), associations whitened by ``var`` (m,), the correction's prior (mean,
    information): pose, correction, information."""
    order = len(x) // 6
    R, t = T0[:3, :3].copy(), T0[:3, 3].copy()
    x = x.copy()
    Q = block_moments(moments, order)
    ev, V = np.linalg.eigh(Q)
    L = np.sqrt(np.maximum(ev, 0.0))[:, :, None] * np.swapaxes(V, 1, 2)  # rows: residuals
    n, d = M.n[lm], M.d[lm]
    x0, P = prior
    Pfull = np.zeros((6 * (order + 1), 6 * (order + 1)))
    Pfull[6:, 6:] = P
    size = max(median(np.linalg.norm(c, axis=1)), 1.0)
    scale = np.r_[np.ones(3), np.full(3, 1.0 / size), np.ones(6 * order)]
    H = Pfull
    for _ in range(iterations):
        z, Jz = stacked(R, t, n, d, c, x)
        r = np.einsum("mij,mj->mi", L, z)
        J = np.einsum("mij,mjk->mik", L, Jz)
        Wr = 1.0 / var
        H = np.einsum("m,mki,mkj->ij", Wr, J, J) + Pfull
        g = np.einsum("m,mki,mk->i", Wr, J, r) + np.r_[np.zeros(6), P @ (x - x0)]
        dx = newton_step(H, g, scale)
        R = rotation_matrices(dx[:3]) @ R
        t = t + dx[3:6]
        x = x + dx[6:]
        if np.linalg.norm(dx[:3]) < 1e-10 and np.linalg.norm(dx[3:]) < 1e-9:
            break
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T, x, H


def corrected_planes(cur: ScanPlanes, ct: TwistRegistration) -> ScanPlanes:
    """``cur`` with its planes' moments moved by the correction ``ct`` measured (what the
    map is updated with); without time moments (they refer to the old deskewing)."""
    assert cur.time_moments is not None
    x = np.r_[ct.correction, ct.acceleration] if np.any(ct.acceleration) else ct.correction
    N, c, S = corrected_moments(cur.m.c, cur.time_moments, x)
    m = Moments(N, c, S, cur.m.rows.copy())
    return ScanPlanes.of(m, cur.normals, cur.sigma, cur.bias)
