"""Group straight segments into traces, and traces of different scanners into planes.

1. Traces. A scanner sweeps several times per epoch; its segments on one wall in
   successive sweeps are parallel lines displaced by the vehicle's motion (identical when
   it stands still). Segments of one ring in consecutive sweeps are linked when they are
   parallel (within ``trace_parallel_deg`` plus three times their predicted direction
   errors), the centroid of one lies within ``tol + trace_step_m`` of the other's line and
   their extents along it overlap; linked components are *traces*. A trace's moments are
   the sums of its segments' (parallel-axis theorem), its direction the mean of theirs
   weighted by their inverse predicted variances (``N L^2``). This is the "trace" of
   :mod:`planodom.simulation.observability`, and it keeps the few points each sweep puts
   on a narrow wall together (direction known from all sweeps).
2. Seeds. Two traces seed a plane only when they come from different rings (scanners),
   cross at ``min_cross_angle_deg`` or more, their predicted direction errors are at most
   ``max_seed_direction_error_deg`` and they are coplanar: the gap between their lines is
   within the noise of their centroids, ``floor + 3 sigma sqrt(1 / N_i + 1 / N_j)`` (at
   most the member tolerance), plus the slack of their direction errors. A pair whose
   lines cross at an end of both (an "L") may be two traces of two walls that meet at a
   corner, ending there: such seeds are tried only after every other seed.
   Traces of one ring never seed: they are parallel or lie in one scan plane.
3. Growth. Seeds are taken greedily, the one whose plane gathers the most points first;
   every available trace whose RMS distance to the plane and whose end points lie within
   the tolerance joins, the plane is refit from the members' moments (total least
   squares) and the members re-collected. The group is a plane only if it still holds
   its seed pair, has ``min_points`` points, its RMS residual is at most ``max_rms_m``
   and, at high noise, it holds ``min_traces`` traces (see
   :func:`required_traces`). Members of an accepted plane are not used again.

So a plane always contains two non-parallel traces of two scanners: a set of parallel
traces is never accepted, and a plane is never guessed from one trace.

Time windows (points not deskewed, ``max_span_s`` finite): each point is in the base frame
of its own time, so traces of successive sweeps are displaced by the motion between them.
Then segments merge into a trace only within one sweep, two traces seed a plane only when
their times lie within ``max_span_s`` (about one sweep), and a trace joins a seed's plane
only when its times lie in the window of ``max_span_s`` centred on the seed's: every plane
is fit to points taken within one window (the crossing traces of a scanner pair in the
same sweep), between which the vehicle moved little. L-shaped seeds are not used then
(one sweep's L is two lines meeting at a corner, with nothing else to confirm it). One
wall gives a plane per window; the caller keeps one
(:func:`planodom.extraction.pipeline.drop_repeats`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from planodom.extraction.kernels import find_root
from planodom.extraction.segments import Segments

#: Segments after each one (same ring, in time order) searched for its continuation in
#: later sweeps: about 4 sweeps of ~8 segments each.
LINK_BAND = 32

# The linking, seeding and greedy growth below are compiled with numba: they are loops
# over a few hundred segments and a few tens of traces with per-step decisions (a greedy
# loop whose every step refits a plane), where numpy pays its per-call overhead tens of
# times per step; no library implements this grouping.


@dataclass(frozen=True, eq=False)
class Traces:
    """Segments of one ring merged over sweeps (module docstring, step 1).

    Attributes:
        label: (S,) trace id of every segment.
        ring, count: (T,) int64. centroid: (T, 3) m. scatter: (T, 3, 3) centred, m^2.
        direction: (T, 3) unit. lo, hi: (T,) extent along the direction, relative to the
        centroid (m). dir_err: (T,) predicted direction error (rad).
        t_lo, t_hi: (T,) first and last acquisition time of its points (s; 0 without
        times).
    """

    label: np.ndarray
    ring: np.ndarray
    count: np.ndarray
    centroid: np.ndarray
    scatter: np.ndarray
    direction: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    dir_err: np.ndarray
    t_lo: np.ndarray
    t_hi: np.ndarray

    def __len__(self) -> int:
        return len(self.ring)


def direction_error(sigma_m: float, count: np.ndarray, length: np.ndarray) -> np.ndarray:
    """Predicted 1-sigma direction error (rad) of a line fit to ``count`` points spread
    over ``length`` m with noise ``sigma_m``: ``sigma sqrt(12 / N) / length``."""
    return sigma_m * np.sqrt(12.0 / np.maximum(count, 1)) / np.maximum(length, 1e-9)


def moment_sums(label, n_lab, count, centroid, scatter):
    """Count, centroid and centred scatter of the unions of items grouped by ``label``."""
    cnt = np.bincount(label, count.astype(np.float64), n_lab)
    cen = (
        np.stack([np.bincount(label, count * centroid[:, k], n_lab) for k in range(3)], axis=1)
        / np.maximum(cnt, 1e-300)[:, None]
    )
    dc = centroid - cen[label]
    full = scatter + count[:, None, None] * dc[:, :, None] * dc[:, None, :]
    sc = np.stack([np.bincount(label, full[:, i, j], n_lab) for i in range(3) for j in range(3)])
    return cnt, cen, sc.T.reshape(-1, 3, 3)


def build_traces(
    segs: Segments,
    tol_m: float,
    sigma_m: float,
    parallel_deg: float,
    step_m: float,
    seg_t0: np.ndarray | None = None,
    seg_t1: np.ndarray | None = None,
    max_span_s: float = np.inf,
) -> Traces:
    """Merge the segments of each ring over its sweeps into :class:`Traces`.

    ``seg_t0``, ``seg_t1`` (S,): first and last time of each segment (s); segments merge
    only when their times lie within ``max_span_s`` (module docstring, time windows).
    Candidate links: each segment with the next ``LINK_BAND`` segments (sorted by ring,
    then time): a few sweeps of the same ring. Sweep ids are not used there: time gaps
    from no-return beams split a sweep into several. Traces are numbered in the order of
    their first segment.
    """
    S = len(segs)
    t0s = np.zeros(S) if seg_t0 is None else np.asarray(seg_t0, dtype=np.float64)
    t1s = np.zeros(S) if seg_t1 is None else np.asarray(seg_t1, dtype=np.float64)
    label, ring, cnt, cen, sc, tdir, lo, hi, t_lo, t_hi = _traces_kernel(
        segs.ring, segs.sweep, segs.count, segs.centroid, segs.scatter, segs.direction,
        segs.length, segs.end0, segs.end1, t0s, t1s, tol_m,
        direction_error(sigma_m, segs.count, segs.length), np.radians(parallel_deg), step_m,
        max_span_s, LINK_BAND,
    )  # fmt: skip
    # Direction error of a trace: all its points over its length.
    err_t = direction_error(sigma_m, cnt, hi - lo)
    return Traces(label, ring, cnt, cen, sc, tdir, lo, hi, err_t, t_lo, t_hi)


@numba.njit(cache=True)
def _traces_kernel(
    ring, sweep, count, centroid, scatter, direction, length, end0, end1, t0s, t1s,
    tol_m, err, parallel_rad, step_m, max_span_s, band,
):  # fmt: skip  # pragma: no cover - compiled
    S = ring.shape[0]
    windowed = np.isfinite(max_span_s)
    parent = np.arange(S)
    for i in range(S):
        for j in range(i + 1, min(i + band + 1, S)):
            if ring[i] != ring[j]:
                continue
            if windowed and (
                sweep[i] != sweep[j] or max(t1s[i], t1s[j]) - min(t0s[i], t0s[j]) > max_span_s
            ):
                continue
            cosang = abs(
                direction[i, 0] * direction[j, 0]
                + direction[i, 1] * direction[j, 1]
                + direction[i, 2] * direction[j, 2]
            )
            if np.sqrt(max(1.0 - cosang * cosang, 0.0)) > np.sin(
                parallel_rad + 3.0 * (err[i] + err[j])
            ):
                continue
            s0 = centroid[j, 0] - centroid[i, 0]
            s1 = centroid[j, 1] - centroid[i, 1]
            s2 = centroid[j, 2] - centroid[i, 2]
            along = s0 * direction[i, 0] + s1 * direction[i, 1] + s2 * direction[i, 2]
            lateral = np.sqrt(max(s0 * s0 + s1 * s1 + s2 * s2 - along * along, 0.0))
            if abs(along) > 0.5 * length[i] + 0.5 * length[j] * cosang + tol_m:
                continue
            if lateral > tol_m + step_m:
                continue
            ri, rj = find_root(parent, i), find_root(parent, j)
            if ri != rj:
                parent[max(ri, rj)] = min(ri, rj)
    # Labels in the order of each component's first segment.
    label = np.empty(S, dtype=np.int64)
    root_label = np.full(S, -1, dtype=np.int64)
    n_lab = 0
    for i in range(S):
        r = find_root(parent, i)
        if root_label[r] < 0:
            root_label[r] = n_lab
            n_lab += 1
        label[i] = root_label[r]
    cnt = np.zeros(n_lab)
    cen = np.zeros((n_lab, 3))
    for i in range(S):
        cnt[label[i]] += count[i]
        for u in range(3):
            cen[label[i], u] += count[i] * centroid[i, u]
    for g in range(n_lab):
        cen[g] /= max(cnt[g], 1e-300)
    sc = np.zeros((n_lab, 3, 3))
    ref = np.zeros((n_lab, 3))
    seen = np.zeros(n_lab, dtype=np.bool_)
    dsum = np.zeros((n_lab, 3))
    t_ring = np.zeros(n_lab, dtype=np.int64)
    t_lo = np.full(n_lab, np.inf)
    t_hi = np.full(n_lab, -np.inf)
    for i in range(S):
        g = label[i]
        for u in range(3):
            du = centroid[i, u] - cen[g, u]
            for v in range(3):
                sc[g, u, v] += scatter[i, u, v] + count[i] * du * (centroid[i, v] - cen[g, v])
        if not seen[g]:  # the first member's direction sets the sign
            seen[g] = True
            ref[g] = direction[i]
        dot = (
            direction[i, 0] * ref[g, 0] + direction[i, 1] * ref[g, 1] + direction[i, 2] * ref[g, 2]
        )
        sg = -1.0 if dot < 0 else 1.0
        # Inverse-variance weights (direction_error^-2 ~ N L^2): a short piece of two
        # points across a corner, tilted by degrees, does not tilt a trace of long ones.
        wgt = count[i] * length[i] * length[i]
        for u in range(3):
            dsum[g, u] += wgt * sg * direction[i, u]
        t_ring[g] = ring[i]
        t_lo[g] = min(t_lo[g], t0s[i])
        t_hi[g] = max(t_hi[g], t1s[i])
    tdir = np.empty((n_lab, 3))
    for g in range(n_lab):
        nrm = np.sqrt(dsum[g, 0] ** 2 + dsum[g, 1] ** 2 + dsum[g, 2] ** 2)
        tdir[g] = dsum[g] / nrm
    lo = np.full(n_lab, np.inf)
    hi = np.full(n_lab, -np.inf)
    for i in range(S):
        g = label[i]
        a = 0.0
        b = 0.0
        for u in range(3):
            a += (end0[i, u] - cen[g, u]) * tdir[g, u]
            b += (end1[i, u] - cen[g, u]) * tdir[g, u]
        lo[g] = min(lo[g], min(a, b))
        hi[g] = max(hi[g], max(a, b))
    icnt = np.empty(n_lab, dtype=np.int64)
    for g in range(n_lab):
        icnt[g] = np.int64(cnt[g])
    return label, t_ring, icnt, cen, sc, tdir, lo, hi, t_lo, t_hi


def required_traces(sigma_m: float, tol_floor_m: float, min_traces_high_noise: int) -> int:
    """Traces a plane needs: 2 while the noise is below the tolerance floor's order
    (``sigma <= tol_floor_m``), else ``min_traces_high_noise``: at high noise two
    traces of two walls that meet are coplanar within it, a third trace is evidence."""
    return 2 if sigma_m <= tol_floor_m else max(2, min_traces_high_noise)


def group_segments(
    segs: Segments,
    tol_m: float,
    sigma_m: float,
    min_cross_angle_deg: float,
    max_seed_direction_error_deg: float,
    min_points: int,
    max_rms_m: float,
    margin_m: float = 0.2,
    parallel_deg: float = 2.0,
    step_m: float = 0.1,
    min_traces: int = 2,
    seg_t0: np.ndarray | None = None,
    seg_t1: np.ndarray | None = None,
    max_span_s: float = np.inf,
    gap_m: float = np.inf,
    gap_ratio: float = 0.0,
    min_trace_points: int = 3,
    seed_floor_m: float = np.inf,
) -> tuple[list[np.ndarray], int]:
    """Segments grouped into planes.

    Args:
        segs: the epoch's segments.
        tol_m: distance (m) within which a trace must lie of a plane to join it.
        sigma_m: noise sigma (m); predicts direction errors (:func:`direction_error`).
        min_cross_angle_deg: smallest angle between a seed pair's directions (deg).
        max_seed_direction_error_deg: largest predicted direction error of a seed (deg).
        min_points: fewest points of a group.
        max_rms_m: largest RMS residual (m) of a group's points to its plane.
        margin_m: an L-shaped seed pair has its crossing within this (m) of both ends.
        parallel_deg, step_m: trace merging (``trace_parallel_deg``, ``trace_step_m``).
        min_traces: fewest traces in a plane.
        seg_t0, seg_t1, max_span_s: first and last time (s) of each segment (S,) and the
            longest time span (s) of a trace, seed or plane (module docstring, time
            windows); no limit by default.
        gap_m, gap_ratio: a plane keeps only the traces connected to its seed's first
            trace through traces less than ``max(gap_m, gap_ratio * range)`` apart
            (:func:`connected_piece`); coplanar walls with a wider gap between them are
            separate planes. No limit by default.
        min_trace_points: fewest points of a trace (its segments merged over sweeps);
            smaller traces neither seed nor join a plane.
        seed_floor_m: the gap between a seed pair's lines must be at most ``min(tol_m,
            seed_floor_m + 3 sigma sqrt(1 / N_i + 1 / N_j))`` (plus the slack of their
            direction errors): the noise of the gap is that of the two traces' centroids,
            not of single points. No floor (the member tolerance alone) by default.

    Returns:
        A list of (K,) int64 arrays of segment indices, one per plane, and the number of
        seeds rejected after refitting.
    """
    if len(segs) < 2:
        return [], 0
    tr = build_traces(segs, tol_m, sigma_m, parallel_deg, step_m, seg_t0, seg_t1, max_span_s)
    seg_group, n_groups, rejected = _grow_kernel(
        tr.ring, tr.count, tr.centroid, tr.scatter, tr.direction, tr.lo, tr.hi, tr.dir_err,
        tr.t_lo, tr.t_hi, tol_m, np.sin(np.radians(min_cross_angle_deg)),
        np.radians(max_seed_direction_error_deg), float(min_points), max_rms_m, margin_m,
        min_traces, max_span_s, gap_m, gap_ratio, min_trace_points, sigma_m, seed_floor_m,
    )  # fmt: skip
    group_of_seg = seg_group[tr.label]
    order = np.argsort(group_of_seg, kind="stable")
    bounds = np.searchsorted(group_of_seg[order], np.arange(n_groups + 1))
    groups = [order[bounds[g] : bounds[g + 1]] for g in range(n_groups)]
    return groups, int(rejected)


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
def _fits(t, n, d, tol, count, centroid, scatter, direction, lo, hi):  # pragma: no cover
    """Trace ``t``'s RMS distance to the plane (n, d) and its end points (the ends of its
    extent, at its centroid's offset) are within ``tol``."""
    off = centroid[t, 0] * n[0] + centroid[t, 1] * n[1] + centroid[t, 2] * n[2] + d
    q = 0.0
    for u in range(3):
        for v in range(3):
            q += n[u] * scatter[t, u, v] * n[v]
    slope = direction[t, 0] * n[0] + direction[t, 1] * n[1] + direction[t, 2] * n[2]
    ends = max(abs(off + slope * lo[t]), abs(off + slope * hi[t]))
    return q / count[t] + off * off <= tol * tol and ends <= tol


@numba.njit(cache=True)
def _segment_distance(p0, p1, q0, q1):  # pragma: no cover - compiled
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
def _connected_piece(members, seed, centroid, direction, lo, hi, gap_m, gap_ratio):
    """The traces among ``members`` (bool (T,)) connected to trace ``seed``: two traces
    are linked when the 3D distance between their centre lines (centroid + direction *
    [lo, hi]) is at most ``max(gap_m, gap_ratio * r)``, ``r`` the range (distance from
    the base origin) of the nearer centroid: the rule that splits scan lines into runs
    (:func:`planodom.extraction.segments.run_breaks`)."""
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
    while head < tail:  # breadth-first growth
        i = queue[head]
        head += 1
        for j in range(K):
            if reach[j]:
                continue
            lim = max(gap_m, gap_ratio * min(rng[i], rng[j]))
            if _segment_distance(a0[i], a1[i], a0[j], a1[j]) <= lim:
                reach[j] = True
                queue[tail] = j
                tail += 1
    out = np.zeros_like(members)
    for k in range(K):
        if reach[k]:
            out[idx[k]] = True
    return out


@numba.njit(cache=True)
def _grow_kernel(
    ring, count_i, centroid, scatter, direction, lo, hi, dir_err, t_lo, t_hi, tol_m,
    sin_min_cross, max_seed_err, min_points, max_rms_m, margin_m, min_traces, max_span_s,
    gap_m, gap_ratio, min_trace_points, sigma_m, seed_floor_m,
):  # fmt: skip  # pragma: no cover - compiled
    """Seeds, membership and greedy growth (module docstring, steps 2 and 3). Returns the
    group of every trace (-1: none), the number of groups and of rejected seeds."""
    T = ring.shape[0]
    count = count_i.astype(np.float64)
    windowed = np.isfinite(max_span_s)
    big = count_i >= min_trace_points
    ok = big & (dir_err <= max_seed_err)
    # Seed pairs, in (i, j), i < j order.
    P_max = T * (T - 1) // 2
    iu = np.empty(P_max, dtype=np.int64)
    ju = np.empty(P_max, dtype=np.int64)
    normals = np.empty((P_max, 3))
    is_l = np.empty(P_max, dtype=np.bool_)
    win_lo = np.empty(P_max)
    win_hi = np.empty(P_max)
    P = 0
    for i in range(T):
        if not ok[i]:
            continue
        for j in range(i + 1, T):
            if not ok[j] or ring[i] == ring[j]:
                continue
            if windowed and max(t_hi[i], t_hi[j]) - min(t_lo[i], t_lo[j]) > max_span_s:
                continue
            # Scalar arithmetic: small-array temporaries cost more than the maths here.
            a0, a1, a2 = direction[i, 0], direction[i, 1], direction[i, 2]
            b0, b1, b2 = direction[j, 0], direction[j, 1], direction[j, 2]
            n0, n1, n2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
            sin_a = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
            if sin_a < sin_min_cross:
                continue
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
            gap_tol = seed_floor_m + 3.0 * sigma_m * np.sqrt(1.0 / count[i] + 1.0 / count[j])
            if gap > min(tol_m, gap_tol) + slack:
                continue
            # Where the two lines cross, along each (relative to its centroid). An L
            # (crossing at an end of both, within the margin) is two walls at a corner.
            c_ = a0 * b0 + a1 * b1 + a2 * b2
            wi = a0 * e0 + a1 * e1 + a2 * e2
            wj = b0 * e0 + b1 * e1 + b2 * e2
            den = max(1.0 - c_ * c_, 1e-12)
            s_i = (c_ * wj - wi) / den
            s_j = (wj - c_ * wi) / den
            mi = max(margin_m, 0.05 * (hi[i] - lo[i]))
            mj = max(margin_m, 0.05 * (hi[j] - lo[j]))
            end_i = min(abs(s_i - lo[i]), abs(s_i - hi[i])) <= mi
            end_j = min(abs(s_j - lo[j]), abs(s_j - hi[j])) <= mj
            if windowed and end_i and end_j:
                continue  # one sweep's L is two lines meeting at a corner, nothing else
            iu[P], ju[P] = i, j
            normals[P, 0], normals[P, 1], normals[P, 2] = n0, n1, n2
            is_l[P] = end_i and end_j
            mid_t = 0.5 * (min(t_lo[i], t_lo[j]) + max(t_hi[i], t_hi[j]))
            win_lo[P] = mid_t - 0.5 * max_span_s
            win_hi[P] = mid_t + 0.5 * max_span_s
            P += 1
    group = np.full(T, -1, dtype=np.int64)
    if P == 0:
        return group, 0, 0
    # Membership of every trace in every seed plane (P, T), as in _fits.
    member = np.zeros((P, T), dtype=np.bool_)
    for p in range(P):
        n = normals[p]
        i, j = iu[p], ju[p]
        d = 0.0
        for u in range(3):
            d -= 0.5 * n[u] * (centroid[i, u] + centroid[j, u])
        for t in range(T):
            if not big[t]:
                continue
            if windowed and (t_lo[t] < win_lo[p] or t_hi[t] > win_hi[p]):
                continue
            member[p, t] = _fits(t, n, d, tol_m, count, centroid, scatter, direction, lo, hi)
    weight_sum = count.sum()
    # L seeds come last: the traces of a wall that meets another at a corner are taken
    # by the walls' own crossing pairs first, and the L dies with them. An L that is
    # left is two traces of one wall meeting at its edge (or an unresolved corner).
    tier = np.empty(P)
    scores = np.empty(P)
    for p in range(P):
        tier[p] = 0.0 if is_l[p] else 2.0 * weight_sum + 1.0
        sc = 0.0
        for t in range(T):
            if member[p, t]:
                sc += count[t]
        scores[p] = sc + tier[p]
    alive = np.ones(P, dtype=np.bool_)
    available = big.copy()
    n_groups = 0
    rejected = 0
    while True:
        best = -1
        best_score = -np.inf
        for p in range(P):  # the first maximum, as np.argmax
            sc = scores[p] if alive[p] else -1.0
            if sc > best_score:
                best_score = sc
                best = p
        p = best
        if best_score < 0:  # no seed left
            break
        alive[p] = False
        if best_score - tier[p] < min_points:
            # Scores only fall: this seed never gathers enough points. Not a stop: an L
            # seed (lower tier) may still hold a plane.
            continue
        members = member[p] & available
        members[iu[p]] = True
        members[ju[p]] = True
        in_window = available.copy()
        if windowed:
            for t in range(T):
                in_window[t] = in_window[t] and t_lo[t] >= win_lo[p] and t_hi[t] <= win_hi[p]
        for _ in range(3):
            n, d, rms, total = _plane_of(members, count, centroid, scatter)
            new = np.zeros(T, dtype=np.bool_)
            n_new = 0
            same = True
            for t in range(T):
                new[t] = in_window[t] and _fits(
                    t, n, d, tol_m, count, centroid, scatter, direction, lo, hi
                )
                n_new += new[t]
                same = same and new[t] == members[t]
            if same or n_new < 2:
                break
            members = new
        if np.isfinite(gap_m):  # only the piece of the plane that holds the seed
            members = _connected_piece(
                members, iu[p], centroid, direction, lo, hi, gap_m, gap_ratio
            )
        n, d, rms, total = _plane_of(members, count, centroid, scatter)
        if (
            not (members[iu[p]] and members[ju[p]])
            or total < min_points
            or rms > max_rms_m
            or members.sum() < min_traces
        ):
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
    return group, n_groups, rejected
