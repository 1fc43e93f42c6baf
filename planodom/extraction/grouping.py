"""Group straight segments into traces, and traces of different scanners into planes.

1. Traces. A scanner sweeps several times per epoch; its segments on one wall in
   successive sweeps are parallel lines displaced by the vehicle's motion (identical when
   it stands still). Segments of one ring in consecutive sweeps are linked when they are
   parallel (within ``trace_parallel_deg`` plus three times their predicted direction
   errors), the centroid of one lies within ``tol + trace_step_m`` of the other's line and
   their extents along it overlap; linked components are *traces*. A trace's moments are
   the sums of its segments' (parallel-axis theorem), its direction the count-weighted
   mean of theirs. This is the "trace" of :mod:`planodom.simulation.observability`, and
   it keeps the few points each sweep puts on a narrow wall together (direction known
   from all sweeps).
2. Seeds. Two traces seed a plane only when they come from different rings (scanners),
   cross at ``min_cross_angle_deg`` or more, their predicted direction errors are at most
   ``max_seed_direction_error_deg`` and they are coplanar within the tolerance (plus the
   slack of their direction errors). A pair whose lines cross at an end of both (an "L")
   may be two traces of two walls that meet at a corner, ending there: such seeds are
   tried only after every other seed.
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

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from planodom.extraction.segments import Segments

#: Segments after each one (same ring, in time order) searched for its continuation in
#: later sweeps: about 4 sweeps of ~8 segments each.
LINK_BAND = 32


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
):
    """Merge the segments of each ring over its sweeps into :class:`Traces`.

    ``seg_t0``, ``seg_t1`` (S,): first and last time of each segment (s); segments merge
    only when their times lie within ``max_span_s`` (module docstring, time windows).
    """
    S = len(segs)
    t0s = np.zeros(S) if seg_t0 is None else np.asarray(seg_t0, dtype=np.float64)
    t1s = np.zeros(S) if seg_t1 is None else np.asarray(seg_t1, dtype=np.float64)
    err = direction_error(sigma_m, segs.count, segs.length)
    # Candidate links: each segment with the next LINK_BAND segments (sorted by ring, then
    # time): a few sweeps of the same ring. Sweep ids are not used: time gaps from
    # no-return beams split a sweep into several.
    band = min(LINK_BAND, S - 1)
    i = np.repeat(np.arange(S), band)
    j = i + np.tile(np.arange(1, band + 1), S)
    inside = j < S
    i, j = i[inside], j[inside]
    keep = segs.ring[i] == segs.ring[j]
    i, j = i[keep], j[keep]
    di, dj = segs.direction[i], segs.direction[j]
    cosang = np.abs(np.einsum("ij,ij->i", di, dj))
    sin_tol = np.sin(np.radians(parallel_deg) + 3.0 * (err[i] + err[j]))
    sep = segs.centroid[j] - segs.centroid[i]
    along = np.einsum("ij,ij->i", sep, di)
    lateral = np.sqrt(np.maximum(np.einsum("ij,ij->i", sep, sep) - along * along, 0.0))
    hi_i = 0.5 * segs.length[i]
    hj = 0.5 * segs.length[j] * cosang
    overlap = np.abs(along) <= hi_i + hj + tol_m
    link = (np.sqrt(np.maximum(1.0 - cosang * cosang, 0.0)) <= sin_tol) & overlap
    link &= lateral <= tol_m + step_m
    if np.isfinite(max_span_s):
        # Only pieces of one sweep (links of a chain would add up their spans).
        link &= segs.sweep[i] == segs.sweep[j]
        link &= np.maximum(t1s[i], t1s[j]) - np.minimum(t0s[i], t0s[j]) <= max_span_s
    i, j = i[link], j[link]
    graph = coo_matrix((np.ones(len(i)), (i, j)), shape=(S, S))
    n_lab, label = connected_components(graph, directed=False)
    cnt, cen, sc = moment_sums(label, n_lab, segs.count, segs.centroid, segs.scatter)
    # Direction: count-weighted mean of the members' directions, signs aligned.
    ref = np.zeros((n_lab, 3))
    ref[label[::-1]] = segs.direction[::-1]  # the first member of each trace
    sgn = np.where(np.einsum("ij,ij->i", segs.direction, ref[label]) < 0, -1.0, 1.0)
    w = (segs.count * sgn)[:, None] * segs.direction
    dsum = np.stack([np.bincount(label, w[:, k], n_lab) for k in range(3)], axis=1)
    direction = dsum / np.linalg.norm(dsum, axis=1)[:, None]
    # Extent along it: the members' end points.
    t0 = np.einsum("ij,ij->i", segs.end0 - cen[label], direction[label])
    t1 = np.einsum("ij,ij->i", segs.end1 - cen[label], direction[label])
    lo = np.full(n_lab, np.inf)
    hi = np.full(n_lab, -np.inf)
    np.minimum.at(lo, label, np.minimum(t0, t1))
    np.maximum.at(hi, label, np.maximum(t0, t1))
    ring = np.zeros(n_lab, dtype=np.int64)
    ring[label] = segs.ring
    # Direction error: all the trace's points over its length.
    err_t = direction_error(sigma_m, cnt, hi - lo)
    t_lo = np.full(n_lab, np.inf)
    t_hi = np.full(n_lab, -np.inf)
    np.minimum.at(t_lo, label, t0s)
    np.maximum.at(t_hi, label, t1s)
    return Traces(label, ring, cnt.astype(np.int64), cen, sc, direction, lo, hi, err_t, t_lo, t_hi)


def plane_of(tr: Traces, members: np.ndarray) -> tuple[np.ndarray, float, float, float]:
    """TLS plane of the union of traces ``members`` (bool (T,)) from their moments:
    unit normal (3,), offset d (m), RMS residual (m), number of points."""
    cnt = tr.count[members].astype(np.float64)
    cen = tr.centroid[members]
    total = cnt.sum()
    c = cnt @ cen / total
    dc = cen - c
    scatter = tr.scatter[members].sum(axis=0) + (cnt[:, None] * dc).T @ dc
    vals, vecs = np.linalg.eigh(scatter)
    n = vecs[:, 0]
    return n, float(-n @ c), float(np.sqrt(max(vals[0], 0.0) / total)), float(total)


def _fits(tr: Traces, n: np.ndarray, d: float, tol: float) -> np.ndarray:
    """(T,) bool: a trace's RMS distance to the plane (n, d) and its end points (the ends
    of its extent, at its centroid's offset) are within ``tol``."""
    off = tr.centroid @ n + d
    ms = (np.einsum("i,tij,j->t", n, tr.scatter, n) / tr.count) + off * off
    slope = tr.direction @ n
    ends = np.maximum(np.abs(off + slope * tr.lo), np.abs(off + slope * tr.hi))
    return (ms <= tol * tol) & (ends <= tol)


def connected_piece(
    tr: Traces, members: np.ndarray, seed: int, gap_m: float, gap_ratio: float
) -> np.ndarray:
    """(T,) bool: the traces among ``members`` connected to trace ``seed``.

    Each trace is its centre line (centroid + direction * [lo, hi]); two traces are linked
    when the 3D distance between these segments is at most ``max(gap_m, gap_ratio * r)``,
    ``r`` the range (distance from the base origin) of the nearer centroid: the rule that
    splits scan lines into runs (:func:`planodom.extraction.segments.run_breaks`).
    """
    idx = np.flatnonzero(members)
    K = len(idx)
    s = np.flatnonzero(idx == seed)
    if K <= 1 or len(s) == 0:
        return members
    a0 = tr.centroid[idx] + tr.lo[idx, None] * tr.direction[idx]
    a1 = tr.centroid[idx] + tr.hi[idx, None] * tr.direction[idx]
    ends = np.concatenate([a0, a1])
    if np.linalg.norm(np.ptp(ends, axis=0)) <= gap_m:  # all within one gap: connected
        return members
    i, j = np.triu_indices(K, 1)
    dist = segment_distances(a0[i], a1[i], a0[j], a1[j])
    rng = np.linalg.norm(tr.centroid[idx], axis=1)
    adj = np.eye(K, dtype=bool)
    adj[i, j] = adj[j, i] = dist <= np.maximum(gap_m, gap_ratio * np.minimum(rng[i], rng[j]))
    reach = adj[s[0]]
    while True:  # breadth-first growth (K is a few tens: cheaper than a sparse graph)
        grown = adj[reach].any(axis=0)
        if np.array_equal(grown, reach):
            break
        reach = grown
    out = np.zeros_like(members)
    out[idx[reach]] = True
    return out


def segment_distances(p0, p1, q0, q1) -> np.ndarray:
    """(K,) closest distances between 3D segments ``[p0, p1]`` and ``[q0, q1]`` (K, 3):
    the closest points of the two lines clamped to the first segment, then alternately
    re-projected and clamped on each (exact unless both clamps bind, then within a
    negligible margin for the gap test)."""
    u, v, w = p1 - p0, q1 - q0, p0 - q0
    a = np.einsum("ij,ij->i", u, u)
    b = np.einsum("ij,ij->i", u, v)
    c = np.einsum("ij,ij->i", v, v)
    d = np.einsum("ij,ij->i", u, w)
    e = np.einsum("ij,ij->i", v, w)
    den = a * c - b * b
    safe = den > 1e-12 * np.maximum(a * c, 1e-300)
    sc = np.where(safe, (b * e - c * d) / np.where(safe, den, 1.0), 0.0)
    sc = np.clip(sc, 0.0, 1.0)
    tc = np.clip((b * sc + e) / np.maximum(c, 1e-300), 0.0, 1.0)
    sc = np.clip((b * tc - d) / np.maximum(a, 1e-300), 0.0, 1.0)
    diff = w + sc[:, None] * u - tc[:, None] * v
    return np.linalg.norm(diff, axis=1)


def quad_forms(normals: np.ndarray, scatter: np.ndarray) -> np.ndarray:
    """(P, T) ``n_p^T S_t n_p`` for normals (P, 3) and symmetric matrices (T, 3, 3), as one
    (P, 6) x (6, T) product (a three-operand einsum is ~50x slower here)."""
    n = normals
    nn = np.stack(
        [n[:, 0] ** 2, 2 * n[:, 0] * n[:, 1], 2 * n[:, 0] * n[:, 2], n[:, 1] ** 2,
         2 * n[:, 1] * n[:, 2], n[:, 2] ** 2],
        axis=1,
    )  # fmt: skip
    s6 = scatter.reshape(-1, 9)[:, [0, 1, 2, 4, 5, 8]]
    return nn @ s6.T


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

    Returns:
        A list of (K,) int64 arrays of segment indices, one per plane, and the number of
        seeds rejected after refitting.
    """
    if len(segs) < 2:
        return [], 0
    tr = build_traces(segs, tol_m, sigma_m, parallel_deg, step_m, seg_t0, seg_t1, max_span_s)
    T = len(tr)
    windowed = bool(np.isfinite(max_span_s))
    big = tr.count >= min_trace_points
    ok = big & (tr.dir_err <= np.radians(max_seed_direction_error_deg))
    a, b = np.triu_indices(T, 1)
    keep = ok[a] & ok[b] & (tr.ring[a] != tr.ring[b])
    if windowed:
        span = np.maximum(tr.t_hi[a], tr.t_hi[b]) - np.minimum(tr.t_lo[a], tr.t_lo[b])
        keep &= span <= max_span_s
    iu, ju = a[keep], b[keep]
    di, dj = tr.direction[iu], tr.direction[ju]
    cross = np.cross(di, dj)
    sin_a = np.linalg.norm(cross, axis=1)
    keep = sin_a >= np.sin(np.radians(min_cross_angle_deg))
    iu, ju, cross, sin_a, di, dj = iu[keep], ju[keep], cross[keep], sin_a[keep], di[keep], dj[keep]
    normals = cross / sin_a[:, None]
    sep = tr.centroid[iu] - tr.centroid[ju]
    gap = np.abs(np.einsum("ij,ij->i", normals, sep))
    # The pair's normal is uncertain by about (err_i + err_j) / sin(angle) (rad).
    slack = np.linalg.norm(sep, axis=1) * 2.0 * (tr.dir_err[iu] + tr.dir_err[ju]) / sin_a
    keep = gap <= tol_m + slack
    # Where the two lines cross, along each (relative to its centroid). An L (crossing at
    # an end of both traces, within the margin) is two walls meeting at a corner.
    c_ = np.einsum("ij,ij->i", di, dj)
    wi, wj = np.einsum("ij,ij->i", di, sep), np.einsum("ij,ij->i", dj, sep)
    den = np.maximum(1.0 - c_ * c_, 1e-12)
    s_i = (c_ * wj - wi) / den
    s_j = (wj - c_ * wi) / den
    mi = np.maximum(margin_m, 0.05 * (tr.hi[iu] - tr.lo[iu]))
    mj = np.maximum(margin_m, 0.05 * (tr.hi[ju] - tr.lo[ju]))
    end_i = np.minimum(np.abs(s_i - tr.lo[iu]), np.abs(s_i - tr.hi[iu])) <= mi
    end_j = np.minimum(np.abs(s_j - tr.lo[ju]), np.abs(s_j - tr.hi[ju])) <= mj
    is_l = (end_i & end_j)[keep]
    if windowed:  # one sweep's L is two lines meeting at a corner, no other evidence
        keep[keep] = ~is_l
        is_l = is_l[~is_l]
    iu, ju, normals = iu[keep], ju[keep], normals[keep]
    if len(iu) == 0:
        return [], 0
    mid = 0.5 * (tr.centroid[iu] + tr.centroid[ju])
    offs = -np.einsum("ij,ij->i", normals, mid)
    # Membership of every trace in every seed plane: (P, T), as in _fits.
    off = normals @ tr.centroid.T + offs[:, None]
    var_n = quad_forms(normals, tr.scatter) / tr.count[None, :]
    slope = normals @ tr.direction.T
    ends = np.maximum(np.abs(off + slope * tr.lo), np.abs(off + slope * tr.hi))
    member = (var_n + off * off <= tol_m * tol_m) & (ends <= tol_m) & big[None, :]
    if windowed:  # members lie in a window of max_span_s centred on the seed's times
        half = 0.5 * max_span_s
        mid_t = 0.5 * (np.minimum(tr.t_lo[iu], tr.t_lo[ju]) + np.maximum(tr.t_hi[iu], tr.t_hi[ju]))
        win_lo, win_hi = mid_t - half, mid_t + half
        member &= (tr.t_lo[None, :] >= win_lo[:, None]) & (tr.t_hi[None, :] <= win_hi[:, None])
    weight = tr.count.astype(np.float64)
    # L seeds come last: the traces of a wall that meets another at a corner are taken
    # by the walls' own crossing pairs first, and the L dies with them. An L that is
    # left is two traces of one wall meeting at its edge (or an unresolved corner).
    tier = np.where(is_l, 0.0, 2.0 * weight.sum() + 1.0)
    scores = member @ weight + tier
    alive = np.ones(len(iu), dtype=bool)
    available = big.copy()
    groups: list[np.ndarray] = []
    rejected = 0
    while True:
        masked = np.where(alive, scores, -1.0)
        p = int(np.argmax(masked))
        if masked[p] - tier[p] < min_points:
            break
        alive[p] = False
        members = member[p] & available
        members[iu[p]] = members[ju[p]] = True
        in_window = available
        if windowed:
            in_window = available & (tr.t_lo >= win_lo[p]) & (tr.t_hi <= win_hi[p])
        for _ in range(3):
            n, d, rms, total = plane_of(tr, members)
            new = _fits(tr, n, d, tol_m) & in_window
            if np.array_equal(new, members) or np.count_nonzero(new) < 2:
                break
            members = new
        if np.isfinite(gap_m):  # only the piece of the plane that holds the seed
            members = connected_piece(tr, members, iu[p], gap_m, gap_ratio)
        n, d, rms, total = plane_of(tr, members)
        if (
            not (members[iu[p]] and members[ju[p]])
            or total < min_points
            or rms > max_rms_m
            or np.count_nonzero(members) < min_traces
        ):
            rejected += 1
            # Seeds that both fall in this rejected set would grow into it again.
            alive &= ~(members[iu] & members[ju])
            continue
        idx = np.flatnonzero(members)
        groups.append(idx)
        available[idx] = False
        alive &= available[iu] & available[ju]
        scores -= member[:, idx] @ weight[idx]
    label_groups = [np.flatnonzero(np.isin(tr.label, g)) for g in groups]
    return label_groups, rejected
