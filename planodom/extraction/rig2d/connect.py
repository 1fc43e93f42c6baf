"""Which traces of a plane hang together: the gap rule of the 2D-rig grouping.

A plane keeps only the traces connected to its seed through traces whose centre lines are
at most ``max(gap_m, gap_ratio * range)`` apart (``extraction.plane_gap_m``,
``gap_range_ratio``): the rule that splits scan lines into runs
(:func:`.scanlines.run_breaks`), so that coplanar walls separated by a wider gap are
separate planes. Compiled with numba (called from the grouping's compiled growth).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def segment_distance(p0, p1, q0, q1):  # pragma: no cover - compiled
    """Closest distance between 3D segments [p0, p1] and [q0, q1]: the closest points of
    the two lines clamped to the first segment, then alternately re-projected and clamped
    on each (exact unless both clamps bind, then within a negligible margin for the gap
    test)."""
    u0, u1, u2 = p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]
    v0, v1, v2 = q1[0] - q0[0], q1[1] - q0[1], q1[2] - q0[2]
    w0, w1, w2 = p0[0] - q0[0], p0[1] - q0[1], p0[2] - q0[2]
    a = u0 * u0 + u1 * u1 + u2 * u2
    b = u0 * v0 + u1 * v1 + u2 * v2
    c = v0 * v0 + v1 * v1 + v2 * v2
    d = u0 * w0 + u1 * w1 + u2 * w2
    e = v0 * w0 + v1 * w1 + v2 * w2
    den = a * c - b * b
    sc = (b * e - c * d) / den if den > 1e-12 * max(a * c, 1e-300) else 0.0
    sc = min(max(sc, 0.0), 1.0)
    tc = min(max((b * sc + e) / max(c, 1e-300), 0.0), 1.0)
    sc = min(max((b * tc - d) / max(a, 1e-300), 0.0), 1.0)
    x0 = w0 + sc * u0 - tc * v0
    x1 = w1 + sc * u1 - tc * v1
    x2 = w2 + sc * u2 - tc * v2
    return np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)


@numba.njit(cache=True)
def connected_piece(members, seed, centroid, direction, lo, hi, gap_m, gap_ratio, seed2=-1):
    """The traces among ``members`` (bool (T,)) connected to trace ``seed`` (or, with
    ``seed2`` >= 0, to either of the two traces ``seed``, ``seed2``): two traces
    are linked when the 3D distance between their centre lines (centroid + direction *
    [lo, hi]) is at most ``max(gap_m, gap_ratio * r)``, ``r`` the range (distance from
    the base origin) of the nearer centroid: the rule that splits scan lines into runs
    (:func:`.scanlines.run_breaks`)."""
    idx = np.flatnonzero(members)
    K = idx.shape[0]
    if K <= 1 or not members[seed]:
        return members
    a0 = np.empty((K, 3))
    a1 = np.empty((K, 3))
    bmin = np.full(3, np.inf)
    bmax = np.full(3, -np.inf)
    for k in range(K):
        t = idx[k]
        a0[k] = centroid[t] + lo[t] * direction[t]
        a1[k] = centroid[t] + hi[t] * direction[t]
        for u in range(3):
            bmin[u] = min(bmin[u], a0[k, u], a1[k, u])
            bmax[u] = max(bmax[u], a0[k, u], a1[k, u])
    span = bmax - bmin
    if np.sqrt(span @ span) <= gap_m:  # all within one gap: connected
        return members
    rng = np.empty(K)
    for k in range(K):
        rng[k] = np.sqrt(centroid[idx[k]] @ centroid[idx[k]])
    reach = np.zeros(K, dtype=np.bool_)
    queue = np.empty(K, dtype=np.int64)
    s = 0
    while idx[s] != seed:
        s += 1
    reach[s] = True
    queue[0] = s
    head, tail = 0, 1
    if seed2 >= 0 and members[seed2] and seed2 != seed:
        s2 = 0
        while idx[s2] != seed2:
            s2 += 1
        reach[s2] = True
        queue[1] = s2
        tail = 2
    while head < tail:  # breadth-first growth
        i = queue[head]
        head += 1
        for j in range(K):
            if reach[j]:
                continue
            lim = max(gap_m, gap_ratio * min(rng[i], rng[j]))
            if segment_distance(a0[i], a1[i], a0[j], a1[j]) <= lim:
                reach[j] = True
                queue[tail] = j
                tail += 1
    out = np.zeros_like(members)
    for k in range(K):
        if reach[k]:
            out[idx[k]] = True
    return out


@numba.njit(cache=True)
def tight_seed(tr, count, seeds, s, p):  # pragma: no cover - compiled
    """The grouping's seed ``s`` (``extraction.seed_spans_gap``): its two traces hold a
    plane's worth of points each (``min_points``) and are coplanar within their own noise
    (the gap between their lines within ``3 sigma sqrt(1 / N_i + 1 / N_j)`` plus the slack
    of their direction errors, the seed test of :mod:`.grouping` without its floor): not a
    coincidence of two far traces (short traces of two walls 20 m apart passed the test
    with its slack)."""
    i, j = seeds.i[s], seeds.j[s]
    if count[i] < p.min_points or count[j] < p.min_points:
        return False
    n = seeds.normal[s]
    if abs(n[2]) < p.span_min_nz:  # seed_spans_gap_max_tilt_deg: a wall keeps the gap rule
        return False
    e = tr.centroid[i] - tr.centroid[j]
    gap = abs(n[0] * e[0] + n[1] * e[1] + n[2] * e[2])
    a, b = tr.direction[i], tr.direction[j]
    c = np.cross(a, b)
    sin_a = np.sqrt(c @ c)
    slack = np.sqrt(e @ e) * 2.0 * (tr.dir_err[i] + tr.dir_err[j]) / max(sin_a, 1e-12)
    return gap <= 3.0 * p.sigma_m * np.sqrt(1.0 / count[i] + 1.0 / count[j]) + slack
