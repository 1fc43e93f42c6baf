"""Planes of walls seen by one scanner only: its lines of several sweeps, deskewed.

The grouping (:mod:`.grouping`) builds a plane only from two crossing traces of two
scanners. A wall that only one scanner reaches (a far wall in a turn, a wall on one side
of a tilted pair) gives that scanner one line per sweep. Once the points are deskewed to
the reference time these lines are parallel lines of the wall, displaced across each other
by the vehicle's motion between the sweeps (at a turn rate w a line at range r moves by
``w r`` per second: 0.4 m per 50 ms sweep at 13 deg/s and 35 m) and they span it as
well as two crossing scanners do. With ``extraction.single_scanner_min_sweeps`` (N > 0),
after the crossing seeds have taken their planes:

1. Seeds (:func:`sweep_seed_pairs`). Two traces seed when they come from the same ring,
   from disjoint time spans (two sweeps), are parallel within ``trace_parallel_deg`` plus
   three times their predicted direction errors, overlap along their direction, and lie
   apart across it by more than the member tolerance with the plane's tilt about their
   direction, ``sigma sqrt(1 / N_i + 1 / N_j) / separation`` plus their direction errors,
   within ``max_seed_direction_error_deg``. The normal is ``u x e``: the common direction
   ``u`` and the separation ``e`` across it.
2. Growth as for the crossing seeds (any scanner's traces join).
3. A group is a plane only when it holds at least N distinct lines of the seed's ring
   (:func:`distinct_lines`): any two parallel lines are coplanar (the lines a scan plane
   cuts on the two walls of a corridor are parallel), three lines of different sweeps
   are coplanar only on a plane. So N is at least 3, and epochs of fewer sweeps get
   no such planes.

The price: such a plane's tilt about its lines is the deskewing's, not the wall's (the
lines move across each other by the motion the twist removes): a turn rate off by 1 deg/s
tilts far walls by 4-8 deg, so this is off by default (measured in
:class:`planodom.config.ExtractionConfig`, ``single_scanner_min_sweeps``). :mod:`.onescanner`
can give such planes a covariance that says so (an option, off).

Points not deskewed (time windows) never seed this way: there, the sweeps' lines are
displaced by the motion the reference frame does not remove.

Compiled with numba (called from the grouping's compiled kernel).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def sweep_seed_pairs(tr, p, count, ok):  # pragma: no cover - compiled
    """Step 1 (module docstring) among the traces ``ok`` (T,) bool of ``tr``
    (:class:`.traces.TraceSet`) under ``p`` (:class:`.grouping.GroupingParams`; ``count``
    (T,) float64): seed traces i < j (P,) int64 and their normals (P, 3), in (i, j)
    order."""
    T = tr.ring.shape[0]
    ring, direction, centroid, dir_err = tr.ring, tr.direction, tr.centroid, tr.dir_err
    lo, hi, t_lo, t_hi = tr.lo, tr.hi, tr.t_lo, tr.t_hi
    P_max = T * (T - 1) // 2
    iu = np.empty(P_max, dtype=np.int64)
    ju = np.empty(P_max, dtype=np.int64)
    normals = np.empty((P_max, 3))
    P = 0
    for i in range(T):
        if not ok[i]:
            continue
        for j in range(i + 1, T):
            if not ok[j] or ring[i] != ring[j]:
                continue
            if not (t_hi[i] < t_lo[j] or t_hi[j] < t_lo[i]):
                continue  # one sweep (or no times): not displaced by the motion
            a0, a1, a2 = direction[i, 0], direction[i, 1], direction[i, 2]
            b0, b1, b2 = direction[j, 0], direction[j, 1], direction[j, 2]
            c_ = a0 * b0 + a1 * b1 + a2 * b2
            sg = -1.0 if c_ < 0 else 1.0
            sin_ij = np.sqrt(max(1.0 - c_ * c_, 0.0))
            if sin_ij > np.sin(p.parallel_rad + 3.0 * (dir_err[i] + dir_err[j])):
                continue
            # the common direction, weighted as the traces' own (N L^2)
            wi = count[i] * (hi[i] - lo[i]) ** 2
            wj = count[j] * (hi[j] - lo[j]) ** 2
            u0, u1, u2 = wi * a0 + wj * sg * b0, wi * a1 + wj * sg * b1, wi * a2 + wj * sg * b2
            nu = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
            u0, u1, u2 = u0 / nu, u1 / nu, u2 / nu
            e0 = centroid[j, 0] - centroid[i, 0]
            e1 = centroid[j, 1] - centroid[i, 1]
            e2 = centroid[j, 2] - centroid[i, 2]
            along = e0 * u0 + e1 * u1 + e2 * u2
            if abs(along) > 0.5 * (hi[i] - lo[i] + hi[j] - lo[j]) + p.tol_m:
                continue  # no overlap along the lines: not one wall's
            x0, x1, x2 = e0 - along * u0, e1 - along * u1, e2 - along * u2
            sep = np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
            if sep <= p.tol_m:
                continue  # one line (the same sweep's, or no motion across it)
            tilt = p.sigma_m * np.sqrt(1.0 / count[i] + 1.0 / count[j]) / sep
            if tilt + dir_err[i] + dir_err[j] > p.max_seed_err_rad:
                continue
            n0, n1, n2 = u1 * x2 - u2 * x1, u2 * x0 - u0 * x2, u0 * x1 - u1 * x0
            nn = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
            iu[P], ju[P] = i, j
            normals[P, 0], normals[P, 1], normals[P, 2] = n0 / nn, n1 / nn, n2 / nn
            P += 1
    return iu[:P].copy(), ju[:P].copy(), normals[:P].copy()


@numba.njit(cache=True)
def distinct_lines(tr, members, seed, tol_m):  # pragma: no cover - compiled
    """Step 3: how many distinct lines the member traces (``members`` (T,) bool) of trace
    ``seed``'s ring form: their centroids' offsets across the seed's direction (in the
    plane of the members, along ``n x u``) sorted, counted as one line while less than
    ``tol_m`` (m) apart."""
    T = tr.ring.shape[0]
    u = tr.direction[seed]
    # across u within the plane: towards the member farthest across u
    c0 = tr.centroid[seed]
    best = 0.0
    w = np.zeros(3)
    for t in range(T):
        if members[t] and tr.ring[t] == tr.ring[seed]:
            e = tr.centroid[t] - c0
            x = e - (e @ u) * u
            nx = np.sqrt(x @ x)
            if nx > best:
                best = nx
                w = x / nx
    if best == 0.0:
        return 1
    offs = np.empty(T)
    k = 0
    for t in range(T):
        if members[t] and tr.ring[t] == tr.ring[seed]:
            offs[k] = (tr.centroid[t] - c0) @ w
            k += 1
    o = np.sort(offs[:k])
    lines = 1
    for q in range(1, k):
        if o[q] - o[q - 1] > tol_m:
            lines += 1
    return lines
