"""Group the traces of different scanners into planes: seeds, then greedy growth.

The traces (:mod:`.traces`) are the input.

1. Seeds. Two traces seed a plane only when they come from different rings (scanners),
   cross at ``min_cross_angle_deg`` or more (or down to 2 deg when the pair's normal is
   predicted to ``max_seed_normal_error_deg``), their predicted direction errors are at most
   ``max_seed_direction_error_deg`` and they are coplanar: the gap between their lines is
   within the noise of their centroids, ``floor + 3 sigma sqrt(1 / N_i + 1 / N_j)`` (at
   most the member tolerance), plus the slack of their direction errors. A pair whose
   lines cross at an end of both (an "L") may be two traces of two walls that meet at a
   corner, ending there: such seeds are tried only after every other seed. With
   ``narrow_last`` (``extraction.narrow_seed_last_deg``) the narrow seeds (crossing under
   ``min_cross_angle_deg``) are tried after those, on the traces left.
   Traces of one ring never seed: they are parallel or lie in one scan plane.
2. Growth. Seeds are taken greedily, the one whose plane gathers the most points first;
   every available trace whose RMS distance to the plane and whose end points lie within
   the tolerance joins, the plane is refit from the members' moments (total least
   squares) and the members re-collected; only the traces connected to the seed through
   gaps of at most ``max(plane_gap_m, gap_range_ratio * range)`` stay (with
   ``extraction.gap_bridge``, also the piece of the seed's second trace where one piece's
   plane predicts the other, :mod:`.bridge`). The group is a
   plane only if it still holds its seed pair, has ``min_points`` points and its RMS
   residual is at most ``max_rms_m``. Members of an accepted plane are not used again.

So a plane always contains two non-parallel traces of two scanners: a set of parallel traces is
never accepted, and a plane is never guessed from one trace.

Time windows (points not deskewed, ``max_span_s`` finite, :mod:`.windows`): two traces seed a
plane only when their times lie within ``max_span_s`` (about one sweep), and a trace joins a
seed's plane only when its times lie in the window of ``max_span_s`` centred on the seed's:
every plane is fit to points taken within one window. L-shaped seeds are not used then (one
sweep's L is two lines meeting at a corner, with nothing else to confirm it).

The seeding and greedy growth are compiled with numba: loops over a few tens of traces with
per-step decisions (a greedy loop whose every step refits a plane), where numpy pays its
per-call overhead tens of times per step; no library implements this grouping. Thresholds travel
as one named tuple (:class:`GroupingParams`), the traces as another (:class:`.traces.TraceSet`).
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from planodom.extraction.rig2d.bridge import bridged_piece
from planodom.extraction.rig2d.connect import connected_piece, tight_seed
from planodom.extraction.rig2d.seedconflicts import dominance, release
from planodom.extraction.rig2d.sweeplines import distinct_lines, sweep_seed_pairs
from planodom.extraction.rig2d.tracefit import trace_fits as _fits

#: An L-shaped seed pair has its crossing within this (m), or 5 % of each trace's
#: length, of an end of both.
L_MARGIN_M = 0.2
#: Sine of the narrowest seed crossing (2 deg; below, bends and deskew residue dominate).
SIN_MIN_CROSS_FLOOR = float(np.sin(np.radians(2.0)))


class GroupingParams(NamedTuple):
    """Thresholds of seeding and growth (module docstring), in the kernels' units.

    Attributes:
        tol_m: distance (m) within which a trace must lie of a plane to join it.
        sigma_m: noise sigma (m) of the points.
        sin_min_cross: sine of the smallest angle between a seed pair's directions.
        max_seed_normal_err_rad: narrower pairs seed if (err_i + err_j) / sin <= this.
        max_seed_err_rad: largest predicted direction error of a seed trace (rad).
        min_points: fewest points of a group.
        max_rms_m: largest RMS residual (m) of a group's points to its plane.
        min_trace_points: fewest points of a trace that seeds or joins a plane.
        seed_floor_m: floor of the gap allowed between a seed pair's lines (m).
        gap_m, gap_ratio: traces connect when less than ``max(gap_m, gap_ratio * range)``
            apart (:func:`.connect.connected_piece`); ``gap_m`` inf: no limit.
        max_span_s: longest time span (s) of a trace, seed or plane; inf: no windows.
        margin_m: an L-shaped seed pair has its crossing within this (m) of both ends.
        min_sweep_lines: 0, or the fewest distinct lines of one scanner's sweeps of a
            plane seeded by them (:mod:`.sweeplines`); parallel_rad: their parallelism.
        seed_spans_gap: the piece kept is the one connected to either seed trace when
            they are coplanar within their own noise (``extraction.seed_spans_gap``).
        span_min_nz: ... and their plane's normal has at least this z component in the
            base frame (``extraction.seed_spans_gap_max_tilt_deg``'s cosine; 0: any).
        exclusive_seeds: of two seeds sharing a trace on different planes, the worse
            fit waits (:mod:`.seedconflicts`, ``extraction.exclusive_seeds``).
        narrow_last: narrow seeds (crossing under ``sin_min_cross``) are taken after
            every other seed, L seeds too, on the traces left
            (``extraction.narrow_seed_last_deg``).
        gap_bridge: the piece beyond the gap that holds the seed's second trace joins
            when one piece's plane predicts the other (:mod:`.bridge`,
            ``extraction.gap_bridge: predicted``).
    """

    tol_m: float
    sigma_m: float
    sin_min_cross: float
    max_seed_err_rad: float
    min_points: float
    max_rms_m: float
    min_trace_points: int
    seed_floor_m: float
    gap_m: float
    gap_ratio: float
    max_span_s: float
    max_seed_normal_err_rad: float = 0.0
    margin_m: float = L_MARGIN_M
    min_sweep_lines: int = 0
    parallel_rad: float = 0.0
    seed_spans_gap: bool = False
    span_min_nz: float = 0.0
    exclusive_seeds: bool = False
    narrow_last: bool = False
    gap_bridge: bool = False


class _Seeds(NamedTuple):
    """P seed pairs: traces ``i`` < ``j`` (P,), their plane's normal (P, 3), whether they
    form an L (P,), their time window [win_lo, win_hi] (P,) (s) and the gap between their
    lines in units of its noise, ``gap / sqrt(1 / N_i + 1 / N_j)`` (P,) (m), whether they
    cross beyond the extents of both (P,)."""

    i: np.ndarray
    j: np.ndarray
    normal: np.ndarray
    is_l: np.ndarray
    win_lo: np.ndarray
    win_hi: np.ndarray
    fit: np.ndarray
    beyond: np.ndarray


@numba.njit(cache=True)
def _plane_of(members, count, centroid, scatter):  # pragma: no cover - compiled
    """TLS plane of the union of traces ``members`` (bool (T,)) from their moments:
    unit normal (3,), offset d (m), RMS residual (m), number of points."""
    total = 0.0
    c0 = c1 = c2 = 0.0
    for t in range(members.shape[0]):
        if members[t]:
            w = count[t]
            total += w
            c0 += w * centroid[t, 0]
            c1 += w * centroid[t, 1]
            c2 += w * centroid[t, 2]
    c = np.array([c0 / total, c1 / total, c2 / total])
    sc = np.zeros((3, 3))
    for t in range(members.shape[0]):
        if members[t]:
            d0, d1, d2 = centroid[t, 0] - c[0], centroid[t, 1] - c[1], centroid[t, 2] - c[2]
            w = count[t]
            sc[0, 0] += scatter[t, 0, 0] + w * d0 * d0
            sc[0, 1] += scatter[t, 0, 1] + w * d0 * d1
            sc[0, 2] += scatter[t, 0, 2] + w * d0 * d2
            sc[1, 1] += scatter[t, 1, 1] + w * d1 * d1
            sc[1, 2] += scatter[t, 1, 2] + w * d1 * d2
            sc[2, 2] += scatter[t, 2, 2] + w * d2 * d2
    sc[1, 0], sc[2, 0], sc[2, 1] = sc[0, 1], sc[0, 2], sc[1, 2]
    vals, vecs = np.linalg.eigh(sc)
    n = vecs[:, 0].copy()
    return n, -(n[0] * c[0] + n[1] * c[1] + n[2] * c[2]), np.sqrt(max(vals[0], 0.0) / total), total


@numba.njit(cache=True)
def _seed_pairs(tr, p, count, ok):  # pragma: no cover - compiled
    """Step 1: the seed pairs (:class:`_Seeds`) among the traces ``ok`` (T,) bool, in
    (i, j), i < j order (``count``: (T,) float64)."""
    T = tr.ring.shape[0]
    ring, direction, centroid, dir_err = tr.ring, tr.direction, tr.centroid, tr.dir_err
    lo, hi, t_lo, t_hi = tr.lo, tr.hi, tr.t_lo, tr.t_hi
    windowed = np.isfinite(p.max_span_s)
    P_max = T * (T - 1) // 2
    iu = np.empty(P_max, dtype=np.int64)
    ju = np.empty(P_max, dtype=np.int64)
    normals = np.empty((P_max, 3))
    is_l = np.empty(P_max, dtype=np.bool_)
    win_lo = np.empty(P_max)
    win_hi = np.empty(P_max)
    fit = np.empty(P_max)
    beyond = np.empty(P_max, dtype=np.bool_)
    P = 0
    for i in range(T):
        if not ok[i]:
            continue
        for j in range(i + 1, T):
            if not ok[j] or ring[i] == ring[j]:
                continue
            if windowed and max(t_hi[i], t_hi[j]) - min(t_lo[i], t_lo[j]) > p.max_span_s:
                continue
            # Scalar arithmetic: small-array temporaries cost more than the maths here.
            a0, a1, a2 = direction[i, 0], direction[i, 1], direction[i, 2]
            b0, b1, b2 = direction[j, 0], direction[j, 1], direction[j, 2]
            n0, n1, n2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
            sin_a = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
            precise = (dir_err[i] + dir_err[j]) <= p.max_seed_normal_err_rad * sin_a
            if sin_a < p.sin_min_cross and not (precise and sin_a >= SIN_MIN_CROSS_FLOOR):
                continue  # narrow crossings seed only when the pair's normal is known well
            n0, n1, n2 = n0 / sin_a, n1 / sin_a, n2 / sin_a
            e0 = centroid[i, 0] - centroid[j, 0]
            e1 = centroid[i, 1] - centroid[j, 1]
            e2 = centroid[i, 2] - centroid[j, 2]
            gap = abs(n0 * e0 + n1 * e1 + n2 * e2)
            # The pair's normal is uncertain by about (err_i + err_j) / sin(angle) (rad).
            slack = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2) * 2.0 * (dir_err[i] + dir_err[j]) / sin_a
            # The gap between the two lines: its noise is that of the two centroids along
            # the normal, sigma sqrt(1 / N_i + 1 / N_j), far below the per-point tolerance
            # for long traces; the floor covers deskew residue and trace curvature.
            gap_tol = p.seed_floor_m + 3.0 * p.sigma_m * np.sqrt(1.0 / count[i] + 1.0 / count[j])
            if gap > min(p.tol_m, gap_tol) + slack:
                continue
            # Where the two lines cross, along each (relative to its centroid). An L
            # (crossing at an end of both, within the margin) is two walls at a corner.
            c_ = a0 * b0 + a1 * b1 + a2 * b2
            wi = a0 * e0 + a1 * e1 + a2 * e2
            wj = b0 * e0 + b1 * e1 + b2 * e2
            den = max(1.0 - c_ * c_, 1e-12)
            s_i = (c_ * wj - wi) / den
            s_j = (wj - c_ * wi) / den
            mi = max(p.margin_m, 0.05 * (hi[i] - lo[i]))
            mj = max(p.margin_m, 0.05 * (hi[j] - lo[j]))
            end_i = min(abs(s_i - lo[i]), abs(s_i - hi[i])) <= mi
            end_j = min(abs(s_j - lo[j]), abs(s_j - hi[j])) <= mj
            if windowed and end_i and end_j:
                continue  # one sweep's L is two lines meeting at a corner, nothing else
            iu[P], ju[P] = i, j
            normals[P, 0], normals[P, 1], normals[P, 2] = n0, n1, n2
            is_l[P] = end_i and end_j
            mid_t = 0.5 * (min(t_lo[i], t_lo[j]) + max(t_hi[i], t_hi[j]))
            win_lo[P] = mid_t - 0.5 * p.max_span_s
            win_hi[P] = mid_t + 0.5 * p.max_span_s
            fit[P] = gap / np.sqrt(1.0 / count[i] + 1.0 / count[j])
            beyond[P] = not (lo[i] <= s_i <= hi[i] or lo[j] <= s_j <= hi[j])
            P += 1
    fit, beyond = fit[:P], beyond[:P]
    return _Seeds(iu[:P], ju[:P], normals[:P], is_l[:P], win_lo[:P], win_hi[:P], fit, beyond)


@numba.njit(cache=True)
def _membership(tr, p, count, big, seeds):  # pragma: no cover - compiled
    """(P, T) bool: trace t fits seed s's plane (through the midpoint of its pair's
    centroids, :func:`_fits`) and lies in its time window."""
    P, T = seeds.i.shape[0], tr.ring.shape[0]
    member = np.zeros((P, T), dtype=np.bool_)
    # The arrays out of the named tuples once (see _fits): ~0.5 us per pair through them.
    centroid, scatter, direction, lo, hi = tr.centroid, tr.scatter, tr.direction, tr.lo, tr.hi
    t_lo, t_hi, win_lo, win_hi = tr.t_lo, tr.t_hi, seeds.win_lo, seeds.win_hi
    windowed, tol = np.isfinite(p.max_span_s), p.tol_m
    # the columns contiguous, for the branch-free first pass below
    c0, c1, c2 = centroid[:, 0].copy(), centroid[:, 1].copy(), centroid[:, 2].copy()
    a0, a1, a2 = direction[:, 0].copy(), direction[:, 1].copy(), direction[:, 2].copy()
    ends_ok = np.empty(T, dtype=np.bool_)
    for s in range(P):
        n = seeds.normal[s]
        n0, n1, n2 = n[0], n[1], n[2]
        i, j = seeds.i[s], seeds.j[s]
        d = 0.0
        for u in range(3):
            d -= 0.5 * n[u] * (centroid[i, u] + centroid[j, u])
        # _fits' end-point test for every trace first (its arithmetic, in its order)
        for t in range(T):
            off = c0[t] * n0 + c1[t] * n1 + c2[t] * n2 + d
            slope = a0[t] * n0 + a1[t] * n1 + a2[t] * n2
            ends_ok[t] = max(abs(off + slope * lo[t]), abs(off + slope * hi[t])) <= tol
        for t in range(T):
            # in its time window (always, without windows)
            if ends_ok[t] and big[t]:
                if not windowed or (t_lo[t] >= win_lo[s] and t_hi[t] <= win_hi[s]):
                    member[s, t] = _fits(centroid, scatter, direction, lo, hi, count, t, n, d, tol)
    return member


@numba.njit(cache=True)
def _grow(tr, p, count, seeds, s, members, available):  # pragma: no cover - compiled
    """Step 2 for seed ``s`` from its initial ``members`` (T,) bool: refit and re-collect
    the available traces in its window (at most three times), keep the piece connected
    to the seed. Returns the members and their plane's RMS residual (m) and point count."""
    T = tr.ring.shape[0]
    centroid, scatter, direction, lo, hi = tr.centroid, tr.scatter, tr.direction, tr.lo, tr.hi
    in_window = available.copy()
    if np.isfinite(p.max_span_s):  # in its time window
        in_window &= (tr.t_lo >= seeds.win_lo[s]) & (tr.t_hi <= seeds.win_hi[s])
    for _ in range(3):
        n, d, rms, total = _plane_of(members, count, centroid, scatter)
        new = np.zeros(T, dtype=np.bool_)
        n_new = 0
        same = True
        for t in range(T):
            new[t] = in_window[t] and _fits(
                centroid, scatter, direction, lo, hi, count, t, n, d, p.tol_m
            )
            n_new += new[t]
            same = same and new[t] == members[t]
        if same or n_new < 2:
            break
        members = new
    if np.isfinite(p.gap_m):  # only the piece of the plane that holds the seed
        seed2 = seeds.j[s] if p.seed_spans_gap and tight_seed(tr, count, seeds, s, p) else -1
        if p.gap_bridge and seed2 < 0:  # the far piece joins where one side predicts it
            members = bridged_piece(tr, count, members, seeds.i[s], seeds.j[s], p.gap_m,
                                    p.gap_ratio, p.tol_m)  # fmt: skip
        else:
            members = connected_piece(members, seeds.i[s], tr.centroid, tr.direction, tr.lo,
                                      tr.hi, p.gap_m, p.gap_ratio, seed2)  # fmt: skip
    n, d, rms, total = _plane_of(members, count, tr.centroid, tr.scatter)
    return members, rms, total


@numba.njit(cache=True)
def _narrow(direction, i, j, sin_min_cross):  # pragma: no cover - compiled
    """Whether traces ``i`` and ``j`` cross under the seeds' smallest angle (a narrow
    seed, admitted by its predicted normal error)."""
    a, b = direction[i], direction[j]
    n0, n1, n2 = a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]
    return np.sqrt(n0 * n0 + n1 * n1 + n2 * n2) < sin_min_cross


@numba.njit(cache=True)
def _grow_kernel(tr, p):  # pragma: no cover - compiled
    """Seeds, membership and greedy growth (module docstring); then, with
    ``min_sweep_lines`` (deskewed points only), the same on the traces left, seeded by
    one scanner's lines of different sweeps (:mod:`.sweeplines`). Returns the group of
    every trace (-1: none), the number of groups and of rejected seeds."""
    T = tr.ring.shape[0]
    count = tr.count.astype(np.float64)
    big = tr.count >= p.min_trace_points
    ok = big & (tr.dir_err <= p.max_seed_err_rad)
    group = np.full(T, -1, dtype=np.int64)
    available = big.copy()
    seeds = _seed_pairs(tr, p, count, ok)
    n_groups, rejected = _greedy(tr, p, count, big, seeds, available, group, 0, 0, False)
    if p.min_sweep_lines > 0 and not np.isfinite(p.max_span_s):
        i, j, normal = sweep_seed_pairs(tr, p, count, ok & available)
        no = np.zeros(i.shape[0])
        nl = np.zeros(i.shape[0], dtype=np.bool_)
        one_ring = _Seeds(i, j, normal, nl, no, no, no, nl)
        n_groups, rejected = _greedy(
            tr, p, count, big, one_ring, available, group, n_groups, rejected, True
        )
    return group, n_groups, rejected


@numba.njit(cache=True)
def _greedy(tr, p, count, big, seeds, available, group, n_groups, rejected, one_ring):
    """Greedy growth from ``seeds`` over the ``available`` traces (both updated in place
    with ``group``); ``one_ring``: seeds of one scanner's sweeps, a group kept only with
    ``min_sweep_lines`` distinct lines of that scanner. Returns the counts of groups and
    of rejected seeds so far."""
    T, P = tr.ring.shape[0], seeds.i.shape[0]
    if P == 0:
        return n_groups, rejected
    iu, ju = seeds.i, seeds.j
    member = _membership(tr, p, count, big, seeds)
    weight_sum = count.sum()
    # L seeds come last: the traces of a wall that meets another at a corner are taken
    # by the walls' own crossing pairs first, and the L dies with them. An L that is
    # left is two traces of one wall meeting at its edge (or an unresolved corner).
    # With ``narrow_last`` narrow seeds come after the L seeds: the default's planes are
    # taken first, whole, and narrow seeds group only the traces they leave.
    tier = np.empty(P)
    scores = np.empty(P)
    step = 2.0 * weight_sum + 1.0  # a tier above every score of the tiers below
    for s in range(P):
        tier[s] = 0.0 if seeds.is_l[s] else step
        if p.narrow_last and not one_ring:  # narrow seeds after all others (docstring)
            tier[s] = (
                0.0 if _narrow(tr.direction, iu[s], ju[s], p.sin_min_cross) else tier[s] + step
            )
        sc = 0.0
        for t in range(T):
            if member[s, t] and available[t]:
                sc += count[t]
        scores[s] = sc + tier[s]
    alive = np.ones(P, dtype=np.bool_)
    exclusive = p.exclusive_seeds and not one_ring
    dom, n_dom = np.zeros((0, 0), dtype=np.bool_), np.zeros(P, dtype=np.int64)
    if exclusive:
        dom, n_dom = dominance(iu, ju, seeds.fit, seeds.is_l, seeds.beyond, member)
    was_alive = alive.copy()
    while True:
        if exclusive:
            release(dom, n_dom, was_alive, alive)
        best = -1
        best_score = -np.inf
        for s in range(P):  # the first maximum, as np.argmax
            sc = scores[s] if alive[s] and n_dom[s] == 0 else -1.0
            if sc > best_score:
                best_score = sc
                best = s
        s = best
        if best_score < 0:  # no seed left
            break
        alive[s] = False
        if best_score - tier[s] < p.min_points:
            # Scores only fall: this seed never gathers enough points. Not a stop: an L
            # seed (lower tier) may still hold a plane.
            continue
        members = member[s] & available
        members[iu[s]] = True
        members[ju[s]] = True
        members, rms, total = _grow(tr, p, count, seeds, s, members, available)
        good = members[iu[s]] and members[ju[s]] and total >= p.min_points
        good = good and rms <= p.max_rms_m
        if good and one_ring:
            good = distinct_lines(tr, members, iu[s], p.tol_m) >= p.min_sweep_lines
        if not good:
            rejected += 1
            # Seeds that both fall in this rejected set would grow into it again.
            for q in range(P):
                if members[iu[q]] and members[ju[q]]:
                    alive[q] = False
            continue
        for t in range(T):
            if members[t]:
                group[t] = n_groups
                available[t] = False
                for q in range(P):
                    if member[q, t]:
                        scores[q] -= count[t]
        n_groups += 1
        for q in range(P):
            alive[q] = alive[q] and available[iu[q]] and available[ju[q]]
    return n_groups, rejected
