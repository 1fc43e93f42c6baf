"""SDA's compiled part (:func:`planodom.association.strict_association`): the gate and
costs of every plane match, the injective assignment (:mod:`planodom.lsap`, scipy's own
algorithm ported so that it runs inside the kernel) and the gated pairs it keeps, in one
call (:func:`sda_kernel`). Before, the costs, scipy's ``linear_sum_assignment`` and the
gate were three calls with their arrays boxed between them, 3-4 times a solve."""

from __future__ import annotations

import numba
import numpy as np

from planodom.lsap import SOLVED, lsap_kernel

#: Cost of a forbidden match in the SDA assignment (gated costs are at most 2).
_FORBIDDEN = 1e6


@numba.njit(cache=True)
def sda_kernel(
    n_p, d_p, c_p, r_p, n_c, d_c, c_c, r_c, R, t, cos_max, d_bound, reach_add
):  # pragma: no cover - compiled
    """:func:`_strict_costs`, the assignment of its costs (:func:`planodom.lsap.
    lsap_kernel`, scipy's) and :func:`_kept_pairs` in one call: (status, (L, 2) intp
    pairs); a status other than :data:`planodom.lsap.SOLVED` (costs scipy rejects:
    NaN, -inf, infeasible) gives no pairs, and the caller lets scipy raise its error."""
    ok, cost = _strict_costs(n_p, d_p, c_p, r_p, n_c, d_c, c_c, r_c, R, t, cos_max, d_bound,
                             reach_add)  # fmt: skip
    status, rows, cols = lsap_kernel(cost)
    if status != SOLVED:
        return status, np.empty((0, 2), dtype=np.intp)
    return status, _kept_pairs(ok, rows, cols)


@numba.njit(cache=True)
def _kept_pairs(ok, rows, cols):  # pragma: no cover - compiled
    """(L, 2) intp the assignment's pairs ``(rows[q], cols[q])`` that pass the gate ``ok``
    (Kp, Kc), in order: ``np.column_stack`` of the kept rows and columns without its
    numpy calls."""
    n = 0
    for q in range(rows.shape[0]):
        n += ok[rows[q], cols[q]]
    out = np.empty((n, 2), dtype=np.intp)
    k = 0
    for q in range(rows.shape[0]):
        if ok[rows[q], cols[q]]:
            out[k, 0], out[k, 1] = rows[q], cols[q]
            k += 1
    return out


@numba.njit(cache=True)
def _strict_costs(
    n_p, d_p, c_p, r_p, n_c, d_c, c_c, r_c, R, t, cos_max, d_bound, reach_add
):  # pragma: no cover - compiled
    """SDA's gate (Kp, Kc) bool and assignment costs (Kp, Kc) (:data:`_FORBIDDEN` where
    gated out) of the current planes ``(n_c, d_c)`` with support centroids ``c_c`` and
    radii ``r_c`` moved by ``(R, t)`` against the previous ones: the arithmetic of
    :func:`planodom.geometry.transform_planes` and of the gates, compiled (a dozen numpy
    calls on 5 x 5 arrays cost several times their arithmetic; SDA runs 3-4 times a
    solve). Unknown supports (NaN) pass the overlap gate."""
    Kp, Kc = len(d_p), len(d_c)
    ok = np.zeros((Kp, Kc), dtype=np.bool_)
    cost = np.full((Kp, Kc), _FORBIDDEN)
    n = np.empty(3)
    c = np.empty(3)
    for j in range(Kc):
        for a in range(3):
            n[a] = R[a, 0] * n_c[j, 0] + R[a, 1] * n_c[j, 1] + R[a, 2] * n_c[j, 2]
            c[a] = R[a, 0] * c_c[j, 0] + R[a, 1] * c_c[j, 1] + R[a, 2] * c_c[j, 2] + t[a]
        d = d_c[j] - (n[0] * t[0] + n[1] * t[1] + n[2] * t[2])
        for i in range(Kp):
            cos = n_p[i, 0] * n[0] + n_p[i, 1] * n[1] + n_p[i, 2] * n[2]
            cos = min(max(cos, -1.0), 1.0)
            dd = abs(d_p[i] - d)
            dist = np.sqrt(
                (c_p[i, 0] - c[0]) ** 2 + (c_p[i, 1] - c[1]) ** 2 + (c_p[i, 2] - c[2]) ** 2
            )
            reach = r_p[i] + r_c[j] + reach_add
            if cos >= cos_max and dd <= d_bound and not dist > reach:
                ok[i, j] = True
                cost[i, j] = (1.0 - cos) / (1.0 - cos_max) + (dd / d_bound) ** 2
    return ok, cost
