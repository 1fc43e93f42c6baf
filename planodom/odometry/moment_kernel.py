"""The moments' residuals and Jacobian in one compiled call (:func:`moment_terms`), for
:func:`planodom.odometry.moment_solve.moment_solve`'s Gauss-Newton.

:func:`planodom.oracle._residuals` and :func:`planodom.odometry.moment_solve.
moment_jacobian` are some twenty numpy calls on arrays of a few rows (an epoch's
associated planes), called at every Gauss-Newton iterate, five a solve: their calls, not
their arithmetic, were most of ``odometry.refinement: moments``'s cost (docs/RESULTS.md
DESKEW13, MOMENTS14).

Here every value is formed with the operations, in the order, of those numpy formulas, so
that the solve's poses stay the same bit for bit (tests/odometry/test_moment_kernel.py
checks both against the numpy forms): elementwise arithmetic as written; numpy's matrix
products as OpenBLAS forms them (each product added to the running sum by a fused
multiply-add, in order: :func:`planodom.fma.dot3`); ``einsum``'s sums over one index as it
adds them (from zero, in index order), its ``ki,ki->k`` as it adds that on x86-64 (the
first and the last term, then the middle, added to its zeroed output), its three-operand
sum with the products formed left to right and the outer summed index outermost.
"""

from __future__ import annotations

import numba
import numpy as np

from planodom.fma import dot3 as _dot3


@numba.njit(cache=True)
def moment_terms(T, npr, ncr, cp, cc, count_p, count_c, off_p, off_c, Lp, Lc):  # pragma: no cover
    """(M,) residuals (:func:`planodom.oracle._residuals`) and (M, 6) Jacobian
    (:func:`planodom.odometry.moment_solve.moment_jacobian`), M = 8 K, at ``T`` (4, 4) of
    K associated planes: previous / current normals ``npr``, ``ncr`` (K, 3), centroids
    ``cp``, ``cc`` (K, 3), point counts (K,), offsets (K,), scatter roots ``Lp``, ``Lc``
    (K, 3, 3)."""
    k_n = npr.shape[0]
    R = T[:3, :3]
    t = T[:3, 3]
    u = np.empty((k_n, 3))  # R^T n_p (npr @ R)
    q = np.empty((k_n, 3))  # R^T (c_p - t) ((cp - t) @ R)
    y = np.empty((k_n, 3))  # R c_c + t (cc @ R.T + t)
    v = np.empty((k_n, 3))  # R n_c (ncr @ R.T)
    for k in range(k_n):
        d0, d1, d2 = cp[k, 0] - t[0], cp[k, 1] - t[1], cp[k, 2] - t[2]
        for i in range(3):
            u[k, i] = _dot3(npr[k, 0], npr[k, 1], npr[k, 2], R[0, i], R[1, i], R[2, i])
            q[k, i] = _dot3(d0, d1, d2, R[0, i], R[1, i], R[2, i])
            y[k, i] = _dot3(cc[k, 0], cc[k, 1], cc[k, 2], R[i, 0], R[i, 1], R[i, 2]) + t[i]
            v[k, i] = _dot3(ncr[k, 0], ncr[k, 1], ncr[k, 2], R[i, 0], R[i, 1], R[i, 2])
    m = 8 * k_n
    r = np.empty(m)
    J = np.zeros((m, 6))
    ob, oc, oe = 3 * k_n, 4 * k_n, 7 * k_n  # the blocks' first rows: a, b, c, e
    su = np.empty((3, 3))
    sn = np.empty((3, 3))
    for k in range(k_n):
        sc, sp = np.sqrt(count_c[k]), np.sqrt(count_p[k])
        _skew_into(u[k, 0], u[k, 1], u[k, 2], su)
        _skew_into(ncr[k, 0], ncr[k, 1], ncr[k, 2], sn)
        for i in range(3):
            acc_a = 0.0
            acc_c = 0.0
            for j in range(3):
                acc_a = acc_a + Lc[k, j, i] * u[k, j]
            for j in range(3):
                acc_c = acc_c + Lp[k, j, i] * v[k, j]
            r[3 * k + i] = acc_a
            r[oc + 3 * k + i] = acc_c
            for col in range(3):
                ja = 0.0
                for j in range(3):
                    ja = ja + Lc[k, j, i] * su[j, col]
                jc = 0.0
                for j in range(3):
                    for mm in range(3):
                        jc = jc + Lp[k, j, i] * R[j, mm] * sn[mm, col]
                J[3 * k + i, col] = ja
                J[oc + 3 * k + i, col] = -jc
        pb = 0.0 + ((npr[k, 0] * y[k, 0] + npr[k, 2] * y[k, 2]) + npr[k, 1] * y[k, 1])
        r[ob + k] = sc * (pb + off_p[k])
        pe = 0.0 + ((ncr[k, 0] * q[k, 0] + ncr[k, 2] * q[k, 2]) + ncr[k, 1] * q[k, 1])
        r[oe + k] = sp * (pe + off_c[k])
        a0, a1, a2, b0, b1, b2 = cc[k, 0], cc[k, 1], cc[k, 2], u[k, 0], u[k, 1], u[k, 2]
        J[ob + k, 0] = sc * (a1 * b2 - a2 * b1)
        J[ob + k, 1] = sc * (a2 * b0 - a0 * b2)
        J[ob + k, 2] = sc * (a0 * b1 - a1 * b0)
        J[ob + k, 3], J[ob + k, 4], J[ob + k, 5] = sc * b0, sc * b1, sc * b2
        a0, a1, a2, b0, b1, b2 = q[k, 0], q[k, 1], q[k, 2], ncr[k, 0], ncr[k, 1], ncr[k, 2]
        J[oe + k, 0] = -sp * (a1 * b2 - a2 * b1)
        J[oe + k, 1] = -sp * (a2 * b0 - a0 * b2)
        J[oe + k, 2] = -sp * (a0 * b1 - a1 * b0)
        J[oe + k, 3], J[oe + k, 4], J[oe + k, 5] = -sp * b0, -sp * b1, -sp * b2
    return r, J


@numba.njit(cache=True)
def _skew_into(x, y, w, out):  # pragma: no cover - compiled
    """``out`` (3, 3) = the cross-product matrix of ``(x, y, w)``, its entries as
    :func:`planodom.odometry.moment_solve._skew` forms them (zeros and negations)."""
    out[0, 0], out[0, 1], out[0, 2] = 0.0, -w, y
    out[1, 0], out[1, 1], out[1, 2] = w, 0.0, -x
    out[2, 0], out[2, 1], out[2, 2] = -y, x, 0.0
