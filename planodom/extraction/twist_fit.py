"""An epoch's deskewing twist from its own planes: coplanarity of points seen at different times.

A wall seen by several scanners or sweeps at different times is a plane only when its
points are deskewed with the right twist. :func:`fit_twist` estimates the constant body
twist ``xi = (w, v)`` (rad/s, m/s, base frame at the reference time, as
:mod:`planodom.extraction.deskew`) by Gauss-Newton on the point-to-plane residuals of
the planes' inliers, each plane's ``(n, d)`` eliminated, with a Gaussian prior on the
twist (the predicted one).

Model. Point ``i`` of a plane, seen ``t_i`` after the reference time, deskewed with ``xi``:
``p_i = exp(t_i xi) p_raw_i``. Changing the twist by ``dxi`` moves it, to first order, by
``dw' x p_i + dv'`` with ``(dw', dv') = J_l(t_i xi) t_i dxi`` (``J_l`` the left Jacobian
of SE(3), here to second order: ``I + A / 2 + A^2 / 6``, ``A = t_i ad(xi)``; at the
0.1 s and 0.5 rad/s of an epoch the rest is ~1e-6 of the step). Along the plane's normal
that is ``g_i . dxi`` with ``g_i = t_i J_l^T (p_i x n, n)``: the algebra of
:func:`planodom.extraction.planes.fit.deskew_jacobian`. The residual ``r_i = n . p_i + d``
also moves with the plane's own perturbation ``phi_i = (1, e1 . q_i, e2 . q_i)``
(offset, tilts about its two tangent axes; ``q_i = p_i - c``). The TLS fit makes
``sum phi_i r_i = 0``, and eliminating the plane (Schur complement) leaves, per plane,

    H = sum g_i g_i^T - G^T A^-1 G,   b = sum r_i g_i,
    G = sum phi_i g_i^T (3, 6),       A = sum phi_i phi_i^T = diag(K, l1, l2)

(``l1, l2`` the scatter's two large eigenvalues: the centred tangent coordinates are
uncorrelated). With point noise ``s`` and the prior ``(xi_p, P)`` the step is

    dxi = -(sum H / s^2 + P)^-1 (sum b / s^2 + P (xi - xi_p)),

after which the raw inliers are deskewed again exactly and the planes refit. Directions
the planes do not observe (one wall, a corridor's length) have no information beyond the
prior and keep it. The information returned, ``sum H / s^2 + P`` at the solution, is the
twist's inverse covariance (first order).

Two compiled passes over the concatenated inliers (numba, :func:`normal_equations`) and
a batched 3x3 eigen-decomposition per plane (the planes' refit) between them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np

from planodom.extraction.deskew import check_twist, deskew_points


@dataclass(frozen=True, eq=False)
class TwistFit:
    """The result of :func:`fit_twist`.

    Attributes:
        twist: (6,) the estimated body twist ``(wx, wy, wz, vx, vy, vz)``, rad/s and m/s.
        information: (6, 6) its information (inverse covariance) including the prior,
            (rad/s, m/s)^-2.
        data_information: (6, 6) the planes' part of it (without the prior).
        iterations: Gauss-Newton steps taken.
        converged: whether the last step was below ``tolerance``.
        rms_m: rms point-to-plane residual (m) of the inliers at the solution.
        observed: (6,) bool, the eigen-directions of the data information that it
            determines better than the prior (eigenvalue above that of the prior along
            it), counted per axis of the eigenbasis; its sum is the observed rank.
        displacement_information: (6, 6) ``sum g g^T / s^2`` over the inliers: a change
            ``dxi`` of the twist moves them along their normals by ``dxi^T M dxi`` noise
            variances summed (the planes' own motion included, which ``data_information``
            leaves out). Zeros without planes.
    """

    twist: np.ndarray
    information: np.ndarray
    data_information: np.ndarray
    iterations: int
    converged: bool
    rms_m: float
    observed: np.ndarray
    displacement_information: np.ndarray

    @property
    def rank(self) -> int:
        """Number of twist directions the planes observe better than the prior."""
        return int(np.count_nonzero(self.observed))


def fit_twist(
    points: np.ndarray,
    t: np.ndarray,
    inliers: Sequence[np.ndarray],
    prior: np.ndarray,
    prior_information: np.ndarray,
    sigma_m: float,
    max_iterations: int = 4,
    tolerance: float = 1e-10,
    start: np.ndarray | None = None,
    step_sigmas: float = 0.0,
    evaluate_solution: bool = True,
) -> TwistFit:
    """The twist that makes each plane's inliers coplanar (module docstring).

    Args:
        points: (N, 3) raw points, metres, each in the base frame of its own time.
        t: (N,) seconds relative to the reference time.
        inliers: per plane, (K,) int64 indices into ``points`` (K >= 3; smaller sets are
            skipped).
        prior: (6,) the predicted twist (rad/s, m/s), also the start.
        prior_information: (6, 6) its information, symmetric positive semi-definite.
        sigma_m: point noise along the normals, metres (> 0).
        max_iterations: at most this many Gauss-Newton steps.
        tolerance: stop when the step's norm (rad/s and m/s together) is below this.
        start: (6,) the first linearisation point (default: the prior), e.g. the twist a
            previous fit of nearly the same planes gave.
        step_sigmas: also stop when the step is below this many standard deviations of
            the twist (its Mahalanobis norm under the information; 0: never).
        evaluate_solution: linearise once more at the solution for the information and
            rms returned; False: they are those of the last linearisation point, one
            step before it (first order the same once the steps are small; saves one
            pass over the inliers; the twist is the same either way).

    Returns:
        :class:`TwistFit`. Without usable planes, the prior with its information.
    """
    xi_p = check_twist(prior)
    assert xi_p is not None
    P = np.asarray(prior_information, dtype=np.float64).reshape(6, 6)
    if not sigma_m > 0:
        raise ValueError(f"sigma_m must be > 0, got {sigma_m}")
    sets = [np.asarray(i, dtype=np.int64) for i in inliers if len(i) >= 3]
    xi = xi_p.copy() if start is None else np.asarray(check_twist(start)).copy()
    empty = np.zeros((6, 6))
    if not sets:
        none = np.zeros(6, dtype=bool)
        return TwistFit(xi_p.copy(), P.copy(), empty, 0, True, 0.0, none, empty)
    idx = np.concatenate(sets)
    bounds = np.cumsum([0] + [len(s) for s in sets])
    raw = np.ascontiguousarray(np.asarray(points, dtype=np.float64)[idx])
    ti = np.asarray(t, dtype=np.float64).reshape(-1)[idx]
    w2 = 1.0 / sigma_m**2
    converged = False
    it = 0
    while True:
        H, b, rms, M = _equations(deskew_points(raw, ti, xi), ti, bounds, xi)
        if converged or it >= max_iterations:
            break
        lhs = H * w2 + P
        rhs = b * w2 + P @ (xi - xi_p)
        dxi = -_solve(lhs, rhs)
        xi = xi + dxi
        it += 1
        converged = bool(np.linalg.norm(dxi) < tolerance)
        converged |= bool(dxi @ lhs @ dxi < step_sigmas**2)
        if not evaluate_solution and (converged or it >= max_iterations):
            break
    info = H * w2
    observed = _observed(info, P)
    return TwistFit(xi, info + P, info, it, converged, rms, observed, M * w2)


def _solve(lhs: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``lhs^-1 rhs`` for a symmetric positive semi-definite ``lhs`` (6, 6): by its
    eigen-decomposition, directions with no information (relative 1e-12) left alone."""
    lam, V = np.linalg.eigh(0.5 * (lhs + lhs.T))
    keep = lam > 1e-12 * max(float(lam[-1]), 1e-300)
    proj = V.T @ rhs
    return V[:, keep] @ (proj[keep] / lam[keep])


def _observed(info: np.ndarray, P: np.ndarray) -> np.ndarray:
    """(6,) bool per eigen-direction of ``info`` (6, 6): whether the data's information
    along it exceeds the prior's."""
    lam, V = np.linalg.eigh(0.5 * (info + info.T))
    prior_along = np.einsum("ik,ij,jk->k", V, P, V)
    return lam > np.maximum(prior_along, 1e-12 * max(float(lam[-1]), 1e-300))


def ad_matrix(xi: np.ndarray) -> np.ndarray:
    """(6, 6) the adjoint ``ad(xi)`` of a twist (w, v) of se(3): ``[[w^, 0], [v^, w^]]``."""
    w, v = xi[:3], xi[3:]
    out = np.zeros((6, 6))
    out[:3, :3] = out[3:, 3:] = _hat(w)
    out[3:, :3] = _hat(v)
    return out


def _hat(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def normal_equations(
    p: np.ndarray, t: np.ndarray, bounds: np.ndarray, xi: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float]:
    """Sum over the planes of ``H`` (6, 6, m^2 s^2 units of ``g g^T``) and ``b`` (6,)
    (module docstring) for the inliers ``p`` (M, 3, metres) deskewed with ``xi`` (6,)
    from times ``t`` (M,, seconds), plane g holding ``p[bounds[g]:bounds[g + 1]]``
    ((G + 1,) int64), and their rms residual (m) after each plane's TLS refit. ``b`` is
    half the gradient of the planes' summed TLS residuals (smallest scatter eigenvalues)
    with the twist, ``H`` their Gauss-Newton half Hessian.

    Two compiled passes over the points (numba, as the extraction's kernels: the numpy
    form made ~20 passes with (M, 6) temporaries and was most of the coplanar deskewing's
    time, ~5 fits per 2D-rig epoch): the planes' centroids and scatters, then, with
    their eigen-decompositions (numpy, batched), the sums ``g g^T``, ``G`` and ``b``."""
    H, b, rms, _ = _equations(p, t, bounds, xi)
    return H, b, rms


def _equations(
    p: np.ndarray, t: np.ndarray, bounds: np.ndarray, xi: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """:func:`normal_equations` and ``sum g g^T`` (6, 6) (before the planes' elimination)."""
    p = np.ascontiguousarray(p, dtype=np.float64)
    t = np.ascontiguousarray(t, dtype=np.float64).reshape(-1)
    bounds = np.ascontiguousarray(bounds, dtype=np.int64)
    c, scatter = _moments_kernel(p, bounds)
    lam, vec = np.linalg.eigh(scatter)  # ascending: n = vec[..., 0]
    count = np.diff(bounds).astype(np.float64)
    A = np.maximum(np.stack([count, lam[:, 2], lam[:, 1]], axis=1), 1e-300)
    ad = np.ascontiguousarray(ad_matrix(xi))
    gg, b, G, ss = _sums_kernel(p, t, bounds, c, np.ascontiguousarray(vec), ad)
    H = gg - np.einsum("pki,pk,pkj->ij", G, 1.0 / A, G)
    return 0.5 * (H + H.T), b, float(np.sqrt(ss / max(len(p), 1))), gg


@numba.njit(cache=True)
def _moments_kernel(p, bounds):  # pragma: no cover - compiled
    """(P, 3) centroids and (P, 3, 3) centred scatters of the planes' points."""
    n_planes = len(bounds) - 1
    c = np.zeros((n_planes, 3))
    S = np.zeros((n_planes, 3, 3))
    for k in range(n_planes):
        a, e = bounds[k], bounds[k + 1]
        for i in range(a, e):
            for j in range(3):
                c[k, j] += p[i, j]
        for j in range(3):
            c[k, j] /= max(e - a, 1)
        for i in range(a, e):
            q0, q1, q2 = p[i, 0] - c[k, 0], p[i, 1] - c[k, 1], p[i, 2] - c[k, 2]
            S[k, 0, 0] += q0 * q0
            S[k, 0, 1] += q0 * q1
            S[k, 0, 2] += q0 * q2
            S[k, 1, 1] += q1 * q1
            S[k, 1, 2] += q1 * q2
            S[k, 2, 2] += q2 * q2
        S[k, 1, 0], S[k, 2, 0], S[k, 2, 1] = S[k, 0, 1], S[k, 0, 2], S[k, 1, 2]
    return c, S


@numba.njit(cache=True)
def _sums_kernel(p, t, bounds, c, vec, ad):  # pragma: no cover - compiled
    """``sum g g^T`` (6, 6), ``b = sum r g`` (6,), per plane ``G = sum phi g^T`` (P, 3, 6)
    and ``sum r^2`` (module docstring; ``g = t (g0 + t (g0 ad / 2 + t g0 ad ad / 6))``,
    ``g0 = (p x n, n)``, the plane's normal ``vec[k, :, 0]``, tangents ``vec[k, :, 2]``,
    ``vec[k, :, 1]``)."""
    n_planes = len(bounds) - 1
    H = np.zeros((6, 6))
    b = np.zeros(6)
    G = np.zeros((n_planes, 3, 6))
    g0 = np.empty(6)
    g1 = np.empty(6)
    g2 = np.empty(6)
    g = np.empty(6)
    ss = 0.0
    for k in range(n_planes):
        n0, n1, n2 = vec[k, 0, 0], vec[k, 1, 0], vec[k, 2, 0]
        for i in range(bounds[k], bounds[k + 1]):
            x, y, z = p[i, 0], p[i, 1], p[i, 2]
            q0, q1, q2 = x - c[k, 0], y - c[k, 1], z - c[k, 2]
            r = q0 * n0 + q1 * n1 + q2 * n2
            ss += r * r
            g0[0], g0[1], g0[2] = y * n2 - z * n1, z * n0 - x * n2, x * n1 - y * n0
            g0[3], g0[4], g0[5] = n0, n1, n2
            for j in range(6):
                s = 0.0
                for m in range(6):
                    s += g0[m] * ad[m, j]
                g1[j] = s
            for j in range(6):
                s = 0.0
                for m in range(6):
                    s += g1[m] * ad[m, j]
                g2[j] = s
            ti = t[i]
            for j in range(6):
                g[j] = ti * (g0[j] + ti * (0.5 * g1[j] + (ti / 6.0) * g2[j]))
            e1 = q0 * vec[k, 0, 2] + q1 * vec[k, 1, 2] + q2 * vec[k, 2, 2]
            e2 = q0 * vec[k, 0, 1] + q1 * vec[k, 1, 1] + q2 * vec[k, 2, 1]
            for j in range(6):
                b[j] += r * g[j]
                G[k, 0, j] += g[j]
                G[k, 1, j] += e1 * g[j]
                G[k, 2, j] += e2 * g[j]
                for m in range(j, 6):
                    H[j, m] += g[j] * g[m]
    for j in range(6):
        for m in range(j):
            H[j, m] = H[m, j]
    return H, b, G, ss
