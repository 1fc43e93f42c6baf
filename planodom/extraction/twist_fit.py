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

Vectorised over points: per-plane moments by ``np.add.reduceat`` over the concatenated
inliers, and a batched 3x3 eigen-decomposition per plane (the planes' refit), no loop
over points.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

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
    """

    twist: np.ndarray
    information: np.ndarray
    data_information: np.ndarray
    iterations: int
    converged: bool
    rms_m: float
    observed: np.ndarray

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

    Returns:
        :class:`TwistFit`. Without usable planes, the prior with its information.
    """
    xi_p = check_twist(prior)
    assert xi_p is not None
    P = np.asarray(prior_information, dtype=np.float64).reshape(6, 6)
    if not sigma_m > 0:
        raise ValueError(f"sigma_m must be > 0, got {sigma_m}")
    sets = [np.asarray(i, dtype=np.int64) for i in inliers if len(i) >= 3]
    xi = xi_p.copy()
    empty = np.zeros((6, 6))
    if not sets:
        return TwistFit(xi, P.copy(), empty, 0, True, 0.0, np.zeros(6, dtype=bool))
    idx = np.concatenate(sets)
    bounds = np.cumsum([0] + [len(s) for s in sets])
    raw = np.ascontiguousarray(np.asarray(points, dtype=np.float64)[idx])
    ti = np.asarray(t, dtype=np.float64).reshape(-1)[idx]
    w2 = 1.0 / sigma_m**2
    converged = False
    it = 0
    H = empty
    while True:
        H, b, rms = normal_equations(deskew_points(raw, ti, xi), ti, bounds, xi)
        if converged or it >= max_iterations:
            break
        lhs = H * w2 + P
        rhs = b * w2 + P @ (xi - xi_p)
        dxi = -_solve(lhs, rhs)
        xi = xi + dxi
        it += 1
        converged = bool(np.linalg.norm(dxi) < tolerance)
    info = H * w2
    return TwistFit(xi, info + P, info, it, converged, rms, _observed(info, P))


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
    with the twist, ``H`` their Gauss-Newton half Hessian."""
    starts = bounds[:-1]
    count = np.diff(bounds).astype(np.float64)
    seg = np.repeat(np.arange(len(count)), np.diff(bounds))
    c = np.add.reduceat(p, starts, axis=0) / count[:, None]
    q = p - c[seg]
    scatter = np.add.reduceat(q[:, :, None] * q[:, None, :], starts, axis=0)
    lam, vec = np.linalg.eigh(scatter)  # ascending: n = vec[..., 0]
    n, e1, e2 = vec[:, :, 0], vec[:, :, 2], vec[:, :, 1]
    ns = n[seg]
    r = np.einsum("mi,mi->m", q, ns)
    g0 = np.hstack([np.cross(p, ns), ns])  # (M, 6): (p x n, n)
    # g = t J_l(t xi)^T g0, J_l ~ I + A / 2 + A^2 / 6, A = t ad(xi): rows g0 @ J_l
    ad = ad_matrix(xi)
    g1 = g0 @ ad
    g = t[:, None] * (g0 + t[:, None] * (0.5 * g1 + (t[:, None] / 6.0) * (g1 @ ad)))
    phi = np.stack(
        [np.ones(len(p)), np.einsum("mi,mi->m", q, e1[seg]), np.einsum("mi,mi->m", q, e2[seg])],
        axis=1,
    )
    G = np.add.reduceat(phi[:, :, None] * g[:, None, :], starts, axis=0)  # (P, 3, 6)
    A = np.stack([count, lam[:, 2], lam[:, 1]], axis=1)
    A = np.maximum(A, 1e-300)
    H = g.T @ g - np.einsum("pki,pk,pkj->ij", G, 1.0 / A, G)
    b = g.T @ r
    return 0.5 * (H + H.T), b, float(np.sqrt(np.mean(r**2)))
