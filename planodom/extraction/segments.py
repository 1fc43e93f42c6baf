"""Split the scan lines of a 2D-scanner rig into straight segments, in scan order.

A ring (one scanner) holds, within one epoch, several successive sweeps. Its points, kept
in scan order, are first cut into runs:

- at a change of ring;
- at a sweep boundary: the time step to the next point exceeds ``sweep_gap_factor`` times
  the median beam interval, or time goes backwards;
- at a spatial gap larger than ``max(min_gap_m, gap_range_ratio * range)``.

Each run is then split recursively at the point farthest from the chord joining its end
points while that distance exceeds the split tolerance (iterative end-point fit, the
"split" of split-and-merge). The recursion is vectorised: each round processes every
pending segment of the epoch at once, so the cost is a few numpy passes per round and the
number of rounds is the depth of the recursion, not the number of segments.

The split runs in 2D: each ring's points are projected on the ring's best-fit plane (its
scan plane, up to the motion left after deskewing), where range noise lies entirely, so a
chord distance costs two products instead of a 3D cross product. Segments are then
described by exact 3D moments of their (deskewed) points; a segment whose 3D line residual
exceeds the split tolerance (a ring that is not planar) is dropped.

The passes over the points (run breaks, ring planes, noise estimate, split, moments) are
compiled with numba: they are short loops with branches over ~10^4 points per epoch, where
numpy needs tens of array passes and temporaries each; no library implements
split-and-merge.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction.kernels import range_moments


@dataclass(frozen=True, eq=False)
class Segments:
    """Straight pieces of scan lines, with the moments needed to fit planes to their unions.

    ``points`` are the scan's points re-ordered by ring (stable, so scan order is kept);
    ``order[i]`` is the index in the scan of ``points[i]``. Segment ``k`` holds
    ``points[starts[k]:ends[k]]``. Only segments that passed the length and count tests
    are listed; the points between them belong to no segment.

    Attributes:
        points: (M, 3) float64 metres. order: (M,) int64.
        starts, ends: (S,) int64.
        ring, sweep: (S,) int64 ring id and epoch-wide sweep id of each segment.
        count: (S,) int64 number of points. centroid: (S, 3) metres.
        scatter: (S, 3, 3) centred scatter matrix ``sum (p - c)(p - c)^T``, m^2.
        direction: (S, 3) unit direction (first principal axis).
        length: (S,) metres, extent along ``direction``.
        rms: (S,) metres, RMS distance of the points to the segment's fitted line.
        end0, end1: (S, 3) metres, the first and last point projected on the line.
    """

    points: np.ndarray
    order: np.ndarray
    starts: np.ndarray
    ends: np.ndarray
    ring: np.ndarray
    sweep: np.ndarray
    count: np.ndarray
    centroid: np.ndarray
    scatter: np.ndarray
    direction: np.ndarray
    length: np.ndarray
    rms: np.ndarray
    end0: np.ndarray
    end1: np.ndarray

    def __len__(self) -> int:
        return len(self.starts)

    def point_indices(self, segs: np.ndarray) -> np.ndarray:
        """Indices into ``points`` of all points of the segments ``segs`` (K,), concatenated."""
        segs = np.asarray(segs, dtype=np.int64)
        return ranges(self.starts[segs], self.ends[segs])


def ranges(starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Concatenation of ``arange(s, e)`` for every pair, vectorised; (sum(e - s),) int64."""
    lens = ends - starts
    total = int(lens.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    offs = np.repeat(starts - np.concatenate([[0], np.cumsum(lens)[:-1]]), lens)
    return np.arange(total, dtype=np.int64) + offs


def run_breaks(
    points: np.ndarray,
    ring: np.ndarray,
    t: np.ndarray | None,
    sweep_gap_factor: float,
    min_gap_m: float,
    gap_range_ratio: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Where runs start, for points sorted by ring in scan order.

    Args:
        points: (M, 3) metres. ring: (M,) ids. t: (M,) seconds or None.

    Returns:
        ``run_start`` (M,) bool, True where a run starts (always at 0), and
        ``sweep_start`` (M,) bool, True where a sweep (or ring) starts.
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    rg = np.ascontiguousarray(ring, dtype=np.int64)
    has_t = t is not None
    tt = np.ascontiguousarray(t, dtype=np.float64) if has_t else np.zeros(len(pts))
    run_start, sweep_start, any_forward = _breaks_kernel(
        pts, rg, tt, has_t, sweep_gap_factor, min_gap_m, gap_range_ratio
    )
    if len(pts) > 1 and not any_forward:
        rev = _angle_reversals(pts, rg)
        sweep_start[1:] |= rev
        run_start[1:] |= rev
    return run_start, sweep_start


@numba.njit(cache=True)
def _breaks_kernel(pts, ring, t, has_t, sweep_gap_factor, min_gap_m, gap_range_ratio):
    """:func:`run_breaks` without the angle test; also whether time ever moves forward."""
    m = pts.shape[0]
    run_start = np.ones(m, dtype=np.bool_)
    sweep_start = np.ones(m, dtype=np.bool_)
    med = 0.0
    any_forward = False
    if has_t and m > 1:
        buf = np.empty(m - 1)
        k = 0
        for i in range(m - 1):
            dt = t[i + 1] - t[i]
            if dt > 0:
                any_forward = True
                if ring[i + 1] == ring[i]:
                    buf[k] = dt
                    k += 1
        if k > 0:
            med = np.median(buf[:k])
    for i in range(1, m):
        new = ring[i] != ring[i - 1]
        if has_t:
            dt = t[i] - t[i - 1]
            new = new or dt < 0 or (med > 0 and dt > sweep_gap_factor * med)
        sweep_start[i] = new
        d0 = pts[i, 0] - pts[i - 1, 0]
        d1 = pts[i, 1] - pts[i - 1, 1]
        d2 = pts[i, 2] - pts[i - 1, 2]
        step = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        rng = np.sqrt(pts[i, 0] ** 2 + pts[i, 1] ** 2 + pts[i, 2] ** 2)
        run_start[i] = new or step > max(min_gap_m, gap_range_ratio * rng)
    return run_start, sweep_start, any_forward


@numba.njit(cache=True)
def _angle_reversals(points, ring):  # pragma: no cover - compiled
    """(M - 1,) bool: where the scan angle of a ring jumps back by more than 60 deg.

    Used when times do not separate the sweeps (no ``t``, or all equal). The angle is
    measured in each ring's best-fit plane (its scan plane) about the base origin, a
    stand-in for the unknown scanner origin that is good enough to see a sweep restart.
    """
    m = points.shape[0]
    out = np.zeros(max(m - 1, 0), dtype=np.bool_)
    lim = np.radians(60.0)
    a = 0
    while a < m:
        b = a + 1
        while b < m and ring[b] == ring[a]:
            b += 1
        if b - a >= 3:
            c = np.empty(3)
            sc = np.empty((3, 3))
            range_moments(points, a, b, c, sc)
            _, vecs = np.linalg.eigh(sc)
            nrm = vecs[:, 0].copy()
            e1 = c - (c @ nrm) * nrm
            ln = np.sqrt(e1 @ e1)
            e1 = e1 / ln if ln > 0 else vecs[:, 2].copy()
            e2 = np.cross(nrm, e1)
            step = np.empty(b - a - 1)
            f0, f1, f2, g0, g1, g2 = e1[0], e1[1], e1[2], e2[0], e2[1], e2[2]
            p = points
            prev = np.arctan2(
                p[a, 0] * g0 + p[a, 1] * g1 + p[a, 2] * g2,
                p[a, 0] * f0 + p[a, 1] * f1 + p[a, 2] * f2,
            )
            for i in range(a + 1, b):
                ang = np.arctan2(
                    p[i, 0] * g0 + p[i, 1] * g1 + p[i, 2] * g2,
                    p[i, 0] * f0 + p[i, 1] * f1 + p[i, 2] * f2,
                )
                d = ang - prev
                d -= 2.0 * np.pi * np.floor((d + np.pi) / (2.0 * np.pi))  # unwrapped step
                step[i - a - 1] = d
                prev = ang
            sign = 1.0 if np.median(step) >= 0 else -1.0
            for k in range(b - a - 1):
                out[a + k] = sign * step[k] < -lim
        a = b
    return out


def estimate_line_noise(points: np.ndarray, run_start: np.ndarray) -> float:
    """Robust estimate (m) of the noise across scan lines from second differences.

    For points ``p[i-1], p[i], p[i+1]`` of a straight run the second difference
    ``p[i-1] - 2 p[i] + p[i+1]`` has, across the line, standard deviation ``sqrt(6) sigma``;
    its component across the local direction ``p[i+2] - p[i-2]`` is taken at every point
    whose five neighbours lie in one run, and ``sigma = median(|.|) / (0.6745 sqrt(6))``.
    Corners and gaps are a small minority and do not move the median. Returns 0 when fewer
    than 10 points qualify.
    """
    m = len(points)
    if m < 15:
        return 0.0
    run_id = np.cumsum(run_start)
    ok = run_id[4:] == run_id[:-4]  # points 2 .. m-3 with all of i-2 .. i+2 in one run
    if np.count_nonzero(ok) < 10:
        return 0.0
    pm1, p0, pp1 = points[1:-3], points[2:-2], points[3:-1]
    direction = points[4:] - points[:-4]
    sec = pm1 - 2.0 * p0 + pp1
    norm = np.linalg.norm(direction, axis=1)
    good = ok & (norm > 0)
    if np.count_nonzero(good) < 10:
        return 0.0
    across = np.linalg.norm(np.cross(sec[good], direction[good]), axis=1) / norm[good]
    return float(np.median(across) / (0.6745 * np.sqrt(6.0)))


@numba.njit(cache=True)
def _split_runs(x, y, starts, ends, tol):  # pragma: no cover - compiled
    """Iterative end-point fit of the runs ``[starts[k], ends[k])`` of 2D points ``(x, y)``
    (M,): each piece is split at its point farthest from the chord joining its ends (the
    first such point) while that distance exceeds ``tol`` (m) and lies strictly inside.
    A chord of length 0 (a closed loop) uses the distance to its start point. Returns the
    final (starts, ends), in order."""
    cap = x.shape[0] + 2 * starts.shape[0] + 1
    out_s = np.empty(cap, dtype=np.int64)
    out_e = np.empty(cap, dtype=np.int64)
    stack_s = np.empty(cap, dtype=np.int64)
    stack_e = np.empty(cap, dtype=np.int64)
    n_out = 0
    for r in range(starts.shape[0]):
        top = 0
        stack_s[0] = starts[r]
        stack_e[0] = ends[r]
        top = 1
        while top > 0:
            top -= 1
            s = stack_s[top]
            e = stack_e[top]
            if e - s < 3:
                out_s[n_out] = s
                out_e[n_out] = e
                n_out += 1
                continue
            ax, ay = x[s], y[s]
            dx, dy = x[e - 1] - ax, y[e - 1] - ay
            clen = np.sqrt(dx * dx + dy * dy)
            mx = -1.0
            arg = s
            if clen > 0:
                ux, uy = dx / clen, dy / clen
                for i in range(s, e):
                    d = abs((x[i] - ax) * uy - (y[i] - ay) * ux)
                    if d > mx:
                        mx = d
                        arg = i
            else:
                for i in range(s, e):
                    d = np.sqrt((x[i] - ax) ** 2 + (y[i] - ay) ** 2)
                    if d > mx:
                        mx = d
                        arg = i
            if mx > tol and s < arg < e:
                # Right piece pushed first: pieces come out in order.
                stack_s[top] = arg
                stack_e[top] = e
                stack_s[top + 1] = s
                stack_e[top + 1] = arg
                top += 2
            else:
                out_s[n_out] = s
                out_e[n_out] = e
                n_out += 1
    return out_s[:n_out].copy(), out_e[:n_out].copy()


@numba.njit(cache=True)
def ring_plane_coordinates(pts, ring_sorted):  # pragma: no cover - compiled
    """2D coordinates (x, y) (M,) of points (M, 3) sorted by ring, in each ring's best-fit
    plane: x along its largest principal axis, y along the second.

    The plane of a ring is fit (TLS) to every k-th of its points (about 256 of them): a
    scan plane is exactly planar in the sensor, and only the motion left after deskewing
    bends it.
    """
    m = pts.shape[0]
    x = np.empty(m)
    y = np.empty(m)
    a = 0
    while a < m:
        b = a + 1
        while b < m and ring_sorted[b] == ring_sorted[a]:
            b += 1
        step = max(1, (b - a) // 256)
        c = np.zeros(3)
        ns = 0
        for i in range(a, b, step):
            c += pts[i]
            ns += 1
        c /= ns
        sc = np.zeros((3, 3))
        for i in range(a, b, step):
            q = pts[i] - c
            for u in range(3):
                for v in range(3):
                    sc[u, v] += q[u] * q[v]
        _, vecs = np.linalg.eigh(sc)
        for i in range(a, b):
            q0, q1, q2 = pts[i, 0] - c[0], pts[i, 1] - c[1], pts[i, 2] - c[2]
            x[i] = q0 * vecs[0, 2] + q1 * vecs[1, 2] + q2 * vecs[2, 2]
            y[i] = q0 * vecs[0, 1] + q1 * vecs[1, 1] + q2 * vecs[2, 1]
        a = b
    return x, y


@numba.njit(cache=True)
def estimate_line_noise_2d(x, y, run_start):  # pragma: no cover - compiled
    """:func:`estimate_line_noise` on 2D points (x, y) (M,) (a ring in its scan plane)."""
    m = x.shape[0]
    if m < 15:
        return 0.0
    across = np.empty(m)
    k = 0
    run = np.cumsum(run_start)
    for c in range(2, m - 2):  # points c with c-2 .. c+2 in one run
        if run[c + 2] != run[c - 2]:
            continue
        dx, dy = x[c + 2] - x[c - 2], y[c + 2] - y[c - 2]
        norm = np.sqrt(dx * dx + dy * dy)
        if not norm > 0:
            continue
        sx = x[c - 1] - 2.0 * x[c] + x[c + 1]
        sy = y[c - 1] - 2.0 * y[c] + y[c + 1]
        across[k] = abs(sx * dy - sy * dx) / norm
        k += 1
    if k < 10:
        return 0.0
    return np.median(across[:k]) / (0.6745 * np.sqrt(6.0))


def split_scan_lines(
    points: np.ndarray, ring: np.ndarray, t: np.ndarray | None, config: ExtractionConfig
) -> tuple[Segments, float]:
    """Straight segments of every ring of a 2D-rig epoch.

    Args:
        points: (N, 3) metres, finite (already deskewed when a twist is known).
        ring: (N,) scanner id of each point; points of one ring in scan order.
        t: (N,) seconds or None, used to find sweep boundaries.
        config: thresholds (``sweep_gap_factor``, ``min_gap_m``, ``gap_range_ratio``,
            ``split_sigma_factor``, ``min_segment_length_m``). Segments of two points are
            kept: one sweep may put only two beams on a narrow or distant wall, and
            :mod:`.grouping` merges them over sweeps before ``min_segment_points`` applies.

    Returns:
        The kept :class:`Segments` and the effective noise sigma (m) used for the
        tolerances (:func:`effective_noise`).
    """
    ring = np.asarray(ring)
    if len(ring) > 1 and np.any(ring[1:] < ring[:-1]):
        key = ring - ring.min()
        # A stable radix sort on small integer keys is ~10x faster than on int64.
        key = key.astype(np.uint16) if key.max() < 65536 else key
        order = np.argsort(key, kind="stable")
    else:
        order = np.arange(len(ring))
    pts = np.ascontiguousarray(points[order], dtype=np.float64)
    rg = ring[order].astype(np.int64)
    tt = None if t is None else t[order]
    run_start, sweep_start = run_breaks(
        pts, rg, tt, config.sweep_gap_factor, config.min_gap_m, config.gap_range_ratio
    )
    x, y = ring_plane_coordinates(pts, rg)
    estimate = estimate_line_noise_2d(x, y, run_start) if config.estimate_noise else 0.0
    sigma = effective_noise(config, estimate)
    split_tol = max(config.split_sigma_factor * sigma, config.tolerance_floor_m)
    starts = np.flatnonzero(run_start)
    ends = np.append(starts[1:], len(pts))
    s, e = _split_runs(x, y, starts, ends, split_tol)
    sweep = np.cumsum(sweep_start) - 1
    segs = segment_features(
        pts,
        order,
        rg,
        sweep,
        s,
        e,
        2,
        config.min_segment_length_m,
        split_tol,
    )
    return segs, sigma


def effective_noise(config: ExtractionConfig, estimate_m: float) -> float:
    """The noise sigma (m) the tolerances scale with: the configured range noise, or the
    noise estimated from the data when that is larger (and ``config.estimate_noise``)."""
    if config.estimate_noise:
        return max(config.range_noise_m, estimate_m)
    return config.range_noise_m


def segment_features(
    pts: np.ndarray,
    order: np.ndarray,
    ring_sorted: np.ndarray,
    sweep_sorted: np.ndarray,
    s: np.ndarray,
    e: np.ndarray,
    min_points: int,
    min_length_m: float,
    max_rms_m: float = np.inf,
) -> Segments:
    """Moments, directions and lengths of the segments ``[s, e)`` of ``pts`` (M, 3), m.

    The direction is the principal axis of the scatter, found by power iteration from the
    chord (it converges in two steps for a line: the ratio of its two largest eigenvalues
    is (noise / length)^2). An end point farther than ``max_rms_m`` from the fitted line
    is dropped and the line refit, up to ``MAX_END_TRIM`` times: the chord of the split
    runs through the end points, so a corner point at an end of a piece is never split
    off, and it would tilt the plane the segment joins. Segments shorter than
    ``min_length_m``, with fewer than ``min_points`` (at least 2) points or an RMS line
    residual above ``max_rms_m`` are dropped.
    """
    s, e, cen, sc, direction, length, rms, t0, t1 = _features_kernel(
        pts, np.asarray(s, dtype=np.int64), np.asarray(e, dtype=np.int64),
        max(min_points, 2), min_length_m, max_rms_m, MAX_END_TRIM,
    )  # fmt: skip
    return Segments(
        points=pts,
        order=order,
        starts=s,
        ends=e,
        ring=ring_sorted[s].astype(np.int64),
        sweep=sweep_sorted[s].astype(np.int64),
        count=e - s,
        centroid=cen,
        scatter=sc,
        direction=direction,
        length=length,
        rms=rms,
        end0=cen + t0[:, None] * direction,
        end1=cen + t1[:, None] * direction,
    )


@numba.njit(cache=True)
def _features_kernel(pts, starts, ends, min_points, min_length_m, max_rms_m, max_trim):
    """Per kept segment: its (trimmed) start and end, centroid (3,), centred scatter
    (3, 3), unit direction, length, RMS line residual and the projections t0, t1 of its
    end points on the line (relative to the centroid)."""
    S = starts.shape[0]
    out_s = np.empty(S, dtype=np.int64)
    out_e = np.empty(S, dtype=np.int64)
    cen = np.empty((S, 3))
    sc = np.empty((S, 3, 3))
    dirs = np.empty((S, 3))
    length = np.empty(S)
    rms = np.empty(S)
    t0 = np.empty(S)
    t1 = np.empty(S)
    k = 0
    c = np.empty(3)
    m = np.empty((3, 3))
    v = np.empty(3)
    w = np.empty(3)
    for g in range(S):
        a, b = starts[g], ends[g]
        fitted = False
        for trim in range(max_trim + 1):
            n = b - a
            if n < min_points:
                break
            fitted = _line_fit(pts, a, b, c, m, v, w)
            if not fitted or trim == max_trim or n <= 2:
                break
            # An end point off the line (a corner point the chord went through): drop it.
            da = _line_distance2(pts, a, c, v)
            db = _line_distance2(pts, b - 1, c, v)
            if max(da, db) <= max_rms_m * max_rms_m:
                break
            if da >= db:
                a += 1
            else:
                b -= 1
            fitted = False
        if not fitted:
            continue
        n = b - a
        lam1 = 0.0
        for u in range(3):
            lam1 += v[u] * (m[u, 0] * v[0] + m[u, 1] * v[1] + m[u, 2] * v[2])
        r = np.sqrt(max(m[0, 0] + m[1, 1] + m[2, 2] - lam1, 0.0) / n)
        a0 = (pts[a, 0] - c[0]) * v[0] + (pts[a, 1] - c[1]) * v[1] + (pts[a, 2] - c[2]) * v[2]
        a1 = (
            (pts[b - 1, 0] - c[0]) * v[0]
            + (pts[b - 1, 1] - c[1]) * v[1]
            + (pts[b - 1, 2] - c[2]) * v[2]
        )
        ln = abs(a1 - a0)
        if ln < min_length_m or r > max_rms_m:
            continue
        out_s[k] = a
        out_e[k] = b
        cen[k] = c
        sc[k] = m
        dirs[k] = v
        length[k] = ln
        rms[k] = r
        t0[k] = a0
        t1[k] = a1
        k += 1
    return (
        out_s[:k].copy(), out_e[:k].copy(), cen[:k].copy(), sc[:k].copy(), dirs[:k].copy(),
        length[:k].copy(), rms[:k].copy(), t0[:k].copy(), t1[:k].copy(),
    )  # fmt: skip


@numba.njit(cache=True)
def _line_fit(pts, a, b, c, m, v, w):  # pragma: no cover - compiled
    """Line through ``pts[a:b]``: fills centroid ``c`` (3,), scatter ``m`` (3, 3) and unit
    direction ``v`` (3,) (power iteration from the chord; ``w`` is scratch). False when
    the direction is undefined (all points equal)."""
    range_moments(pts, a, b, c, m)
    for u in range(3):
        v[u] = pts[b - 1, u] - pts[a, u]
    for _ in range(3):  # power iteration from the chord
        nv = np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        if nv > 0:
            v /= nv
        for u in range(3):
            w[u] = m[u, 0] * v[0] + m[u, 1] * v[1] + m[u, 2] * v[2]
        v[:] = w
    nv = np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if not nv > 0:
        return False
    v /= nv
    return True


@numba.njit(cache=True)
def _line_distance2(pts, i, c, v):  # pragma: no cover - compiled
    """Squared distance (m^2) of ``pts[i]`` to the line through ``c`` along unit ``v``."""
    q0, q1, q2 = pts[i, 0] - c[0], pts[i, 1] - c[1], pts[i, 2] - c[2]
    along = q0 * v[0] + q1 * v[1] + q2 * v[2]
    return max(q0 * q0 + q1 * q1 + q2 * q2 - along * along, 0.0)


#: End points a segment may lose to :func:`_features_kernel`'s trimming, per segment.
MAX_END_TRIM = 3
