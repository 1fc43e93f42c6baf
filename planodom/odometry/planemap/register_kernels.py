"""The plane-map registration's compiled kernels (:mod:`.register`): the Gauss-Newton's
whitened moment residuals and weighted normal equations, and the association's gates and
nearest landmark.

Each forms every value with the operations, in the order, of the numpy formulas it
replaces, so that the registration's poses stay the same bit for bit (checked on the
lidar worlds' runs against the numpy path, call by call): elementwise arithmetic as
written, numpy's three-term ``einsum`` sums as it adds them on x86-64 (the first and the
last term, then the middle), numpy's matrix products as OpenBLAS forms them (each product
added to the running sum by a fused multiply-add, in order: :func:`planodom.fma.fma`). Functions of
numpy's own (``arccos``, its AVX-512 routine) and LAPACK's (eigen-decompositions) stay
outside, in numpy.
"""

from __future__ import annotations

import numba
import numpy as np

from planodom.fma import dot3 as _dot3
from planodom.fma import fma as _fma


@numba.njit(cache=True)
def whitened_kernel(R, t, x, n, d, cov_n, lc, var_o, N, lam, E, s2):  # pragma: no cover
    """:func:`.outliers.whitened` of m associations with the same arithmetic, compiled:
    ``r`` (m, 4), ``J`` (m, 4, 6), ``v`` (m, 4), ``chi2`` (m,) under ``(R, t)`` from ``x =
    c R^T`` (m, 3) (the moved centroids without ``t``, numpy's product), the landmarks'
    ``n`` (m, 3), ``d`` (m,), ``cov_n`` (m, 3, 3), centroids ``lc`` (m, 3) and ``var_o``
    (m,), the planes' ``N`` (m,), ``lam`` (m, 3), ``E`` (m, 3, 3) and noise ``s2`` (m, 4).
    Every element is formed as numpy forms it (module docstring)."""
    m = N.shape[0]
    r = np.empty((m, 4))
    J = np.zeros((m, 4, 6))
    v = np.empty((m, 4))
    chi2 = np.empty(m)
    U = np.empty((3, 3))
    for i in range(m):
        sN = np.sqrt(N[i])
        y0, y1, y2 = x[i, 0] + t[0], x[i, 1] + t[1], x[i, 2] + t[2]
        r[i, 0] = sN * (((n[i, 0] * y0 + n[i, 2] * y2) + n[i, 1] * y1) + d[i])
        J[i, 0, 0] = sN * (x[i, 1] * n[i, 2] - x[i, 2] * n[i, 1])
        J[i, 0, 1] = sN * (x[i, 2] * n[i, 0] - x[i, 0] * n[i, 2])
        J[i, 0, 2] = sN * (x[i, 0] * n[i, 1] - x[i, 1] * n[i, 0])
        J[i, 0, 3] = sN * n[i, 0]
        J[i, 0, 4] = sN * n[i, 1]
        J[i, 0, 5] = sN * n[i, 2]
        for a in range(3):  # U = R E
            for k in range(3):
                U[a, k] = R[a, 0] * E[i, 0, k] + R[a, 1] * E[i, 1, k] + R[a, 2] * E[i, 2, k]
        # the landmark's offset variance at the moved centroid (PlaneMap.var_at)
        e0, e1, e2 = y0 - lc[i, 0], y1 - lc[i, 1], y2 - lc[i, 2]
        q = 0.0
        for a, ea in ((0, e0), (1, e1), (2, e2)):
            q += ea * cov_n[i, a, 0] * e0
            q += ea * cov_n[i, a, 1] * e1
            q += ea * cov_n[i, a, 2] * e2
        v[i, 0] = s2[i, 0] + N[i] * (q + var_o[i])
        for k in range(3):
            sl = np.sqrt(max(lam[i, k], 0.0))
            r[i, k + 1] = sl * (n[i, 0] * U[0, k] + n[i, 1] * U[1, k] + n[i, 2] * U[2, k])
            J[i, k + 1, 0] = sl * (U[1, k] * n[i, 2] - U[2, k] * n[i, 1])
            J[i, k + 1, 1] = sl * (U[2, k] * n[i, 0] - U[0, k] * n[i, 2])
            J[i, k + 1, 2] = sl * (U[0, k] * n[i, 1] - U[1, k] * n[i, 0])
            qk = 0.0
            for a in range(3):
                for b in range(3):
                    qk += U[a, k] * cov_n[i, a, b] * U[b, k]
            v[i, k + 1] = s2[i, k + 1] + lam[i, k] * qk
        chi2[i] = (r[i, 0] ** 2 / v[i, 0] + r[i, 2] ** 2 / v[i, 2] + r[i, 3] ** 2 / v[i, 3]) / 3.0
    return r, J, v, chi2


@numba.njit(cache=True)
def normal_equations_kernel(r, J, v, chi2, k2, c2):  # pragma: no cover - compiled
    """The Cauchy weights ``w`` (m,) of the mean squared whitened residuals ``chi2`` (m,)
    at the kernel scale ``c2`` (squared) times the residual scale ``k2``, and the
    weighted normal equations ``H`` (6, 6), ``g`` (6,) of residuals ``r`` (m, 4),
    Jacobians ``J`` (m, 4, 6) and variances ``v`` (m, 4) (``sum w / (k2 v) J^T J``,
    ``sum w / (k2 v) J^T r``), added in numpy's ``einsum`` order (bit for bit)."""
    m = r.shape[0]
    w = np.empty(m)
    H = np.zeros((6, 6))
    g = np.zeros(6)
    for i in range(m):
        w[i] = 1.0 / (1.0 + chi2[i] / (k2 * c2))
    for i in range(m):
        for k in range(4):
            wr = w[i] / (k2 * v[i, k])
            for a in range(6):
                wa = wr * J[i, k, a]
                g[a] += wa * r[i, k]
                for b in range(6):
                    H[a, b] += wa * J[i, k, b]
    return w, H, g


@numba.njit(cache=True)
def nearest_gated_kernel(  # noqa: PLR0913 - flat for numba
    ang, R, t, c, S, N, var_n, var_o, sigma, Md, Mc, Mradius, Mcov, Mvar_o, Mn, s_r, s_t, bias
):  # pragma: no cover - compiled
    """:func:`.register.associate` with the ``distance`` rule, compiled: (K,) the gated landmark
    with the least ``e^2`` of every scan plane (-1: none; the first of equal ones, as
    ``argmin``), from the angles ``ang`` (K, L) (numpy's ``arccos``), the pose ``R``
    (3, 3), ``t`` (3,), the planes' ``c`` (K, 3), ``S`` (K, 3, 3), ``N``, ``var_n``,
    ``var_o`` (K,) and ``sigma``, and the landmarks' ``Md`` (L,), ``Mc`` (L, 3),
    ``Mradius`` (L,), ``Mcov`` (L, 3, 3), ``Mvar_o`` (L,), ``Mn`` (L, 3). Each value is
    formed as :func:`.register.candidates` and :func:`.register.plane_landmark_errors`
    form it, so the gates decide the same bit for bit."""
    K, L = N.shape[0], Md.shape[0]
    var_nL = np.empty(L)
    Cc = np.empty((L, 3))
    cCc = np.empty(L)
    nn = np.empty((L, 9))
    for m in range(L):
        var_nL[m] = ((Mcov[m, 0, 0] + Mcov[m, 1, 1]) + Mcov[m, 2, 2]) / 2
        for i in range(3):
            Cc[m, i] = (Mcov[m, i, 0] * Mc[m, 0] + Mcov[m, i, 2] * Mc[m, 2]) + Mcov[m, i, 1] * Mc[
                m, 1
            ]
        cCc[m] = (Mc[m, 0] * Cc[m, 0] + Mc[m, 2] * Cc[m, 2]) + Mc[m, 1] * Cc[m, 1]
        for a in range(3):
            for b in range(3):
                nn[m, 3 * a + b] = Mn[m, a] * Mn[m, b]
    out = np.full(K, -1, dtype=np.int64)
    cw = np.empty(3)
    RS = np.empty((3, 3))
    Sw = np.empty(9)
    xx = np.empty(9)
    for k in range(K):
        for a in range(3):
            cw[a] = _dot3(c[k, 0], c[k, 1], c[k, 2], R[a, 0], R[a, 1], R[a, 2]) + t[a]
        for a in range(3):
            for b in range(3):
                xx[3 * a + b] = cw[a] * cw[b]
                RS[a, b] = _dot3(R[a, 0], R[a, 1], R[a, 2], S[k, 0, b], S[k, 1, b], S[k, 2, b])
        for a in range(3):
            for b in range(3):
                Sw[3 * a + b] = _dot3(RS[a, 0], RS[a, 1], RS[a, 2], R[b, 0], R[b, 1], R[b, 2])
        radius = np.sqrt(3.0 * ((S[k, 0, 0] + S[k, 1, 1]) + S[k, 2, 2]) / N[k])
        lever = np.sqrt((c[k, 0] * c[k, 0] + c[k, 1] * c[k, 1]) + c[k, 2] * c[k, 2]) + radius
        v_pose = (s_t + s_r * lever) ** 2
        best = np.inf
        for m in range(L):
            # gates first: the normal's, then the distance's
            g_ang = 3 * np.sqrt(s_r**2 + var_n[k] + var_nL[m])
            if not ang[k, m] <= g_ang:
                continue
            q = xx[0] * Mcov[m, 0, 0]
            for j in range(1, 9):
                q = _fma(xx[j], Mcov[m, j // 3, j % 3], q)
            q2 = _dot3(2.0 * cw[0], 2.0 * cw[1], 2.0 * cw[2], Cc[m, 0], Cc[m, 1], Cc[m, 2])
            vL = ((q - q2) + cCc[m]) + Mvar_o[m]
            g_d2 = 9 * ((((v_pose + var_o[k]) + vL) + sigma**2) + bias**2)
            off = _dot3(cw[0], cw[1], cw[2], Mn[m, 0], Mn[m, 1], Mn[m, 2]) + Md[m]
            q = Sw[0] * nn[m, 0]
            for j in range(1, 9):
                q = _fma(Sw[j], nn[m, j], q)
            e2 = off * off + q / N[k]
            if not e2 <= g_d2:
                continue
            d0, d1, d2 = cw[0] - Mc[m, 0], cw[1] - Mc[m, 1], cw[2] - Mc[m, 2]
            sep = np.sqrt((d0 * d0 + d1 * d1) + d2 * d2) - Mradius[m] - radius
            if sep <= np.sqrt(g_d2) and e2 < best:
                best = e2
                out[k] = m
    return out
