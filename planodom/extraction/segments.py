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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planodom.config import ExtractionConfig


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
    m = len(points)
    sweep_start = np.ones(m, dtype=bool)
    if m == 0:
        return sweep_start, sweep_start
    same_ring = ring[1:] == ring[:-1]
    new_sweep = ~same_ring
    if t is not None:
        dt = np.diff(t)
        valid = same_ring & (dt > 0)
        med = float(np.median(dt[valid])) if np.any(valid) else 0.0
        new_sweep = new_sweep | (dt < 0) | ((dt > sweep_gap_factor * med) & (med > 0))
    if t is None or not np.any(np.diff(t) > 0):
        new_sweep = new_sweep | _angle_reversals(points, ring)
    sweep_start[1:] = new_sweep
    step = np.linalg.norm(np.diff(points, axis=0), axis=1)
    rng = np.linalg.norm(points[1:], axis=1)
    gap = step > np.maximum(min_gap_m, gap_range_ratio * rng)
    run_start = sweep_start.copy()
    run_start[1:] |= gap
    return run_start, sweep_start


def _angle_reversals(points: np.ndarray, ring: np.ndarray) -> np.ndarray:
    """(M - 1,) bool: where the scan angle of a ring jumps back by more than 60 deg.

    Used when times do not separate the sweeps (no ``t``, or all zero). The angle is
    measured in each ring's best-fit plane (its scan plane) about the base origin, a
    stand-in for the unknown scanner origin that is good enough to see a sweep restart.
    """
    out = np.zeros(max(len(points) - 1, 0), dtype=bool)
    bounds = np.flatnonzero(np.diff(ring)) + 1
    for a, b in zip(np.r_[0, bounds], np.r_[bounds, len(points)], strict=True):
        if b - a < 3:
            continue
        q = points[a:b]
        _, _, vt = np.linalg.svd(q - q.mean(axis=0), full_matrices=False)
        e1 = q.mean(axis=0) - (q.mean(axis=0) @ vt[2]) * vt[2]
        e1 = e1 / np.linalg.norm(e1) if np.linalg.norm(e1) > 0 else vt[0]
        e2 = np.cross(vt[2], e1)
        ang = np.unwrap(np.arctan2(q @ e2, q @ e1))
        step = np.diff(ang)
        sign = 1.0 if np.median(step) >= 0 else -1.0
        out[a : b - 1] = sign * step < -np.radians(60.0)
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


def _split_runs(x: np.ndarray, y: np.ndarray, starts: np.ndarray, ends: np.ndarray, tol: float):
    """Iterative end-point fit of all runs at once on 2D points ``(x, y)``; returns the final
    (starts, ends). Hand-written (no library does split-and-merge); one round handles every
    pending segment with a few flat numpy passes."""
    done_s, done_e = [], []
    s, e = starts, ends
    big = np.iinfo(np.int64).max
    while len(s):
        short = (e - s) < 3
        if np.any(short):
            done_s.append(s[short])
            done_e.append(e[short])
            s, e = s[~short], e[~short]
        if len(s) == 0:
            break
        lens = e - s
        idx = ranges(s, e)
        local = np.zeros(len(s), dtype=np.int64)
        np.cumsum(lens[:-1], out=local[1:])
        ax, ay = x[s], y[s]
        dx, dy = x[e - 1] - ax, y[e - 1] - ay
        clen = np.hypot(dx, dy)
        deg = clen <= 0
        clen[deg] = 1.0
        ux, uy = dx / clen, dy / clen
        rx = x[idx] - np.repeat(ax, lens)
        ry = y[idx] - np.repeat(ay, lens)
        dist = np.abs(rx * np.repeat(uy, lens) - ry * np.repeat(ux, lens))
        if np.any(deg):  # closed loop of points: distance to the start point instead
            d_rep = np.repeat(deg, lens)
            dist[d_rep] = np.hypot(rx[d_rep], ry[d_rep])
        mx = np.maximum.reduceat(dist, local)
        arg = np.minimum.reduceat(np.where(dist >= np.repeat(mx, lens), idx, big), local)
        split = (mx > tol) & (arg > s) & (arg < e)
        done_s.append(s[~split])
        done_e.append(e[~split])
        s, e, arg = s[split], e[split], arg[split]
        s, e = np.concatenate([s, arg]), np.concatenate([arg, e])
    fs, fe = np.concatenate(done_s), np.concatenate(done_e)
    order = np.argsort(fs, kind="stable")
    return fs[order], fe[order]


def ring_plane_coordinates(
    pts: np.ndarray, ring_sorted: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """2D coordinates (x, y) (M,) of points sorted by ring, in each ring's best-fit plane.

    The plane of a ring is fit (TLS) to every 8th of its points: a scan plane is exactly
    planar in the sensor, and only the motion left after deskewing bends it.
    """
    bounds = np.flatnonzero(ring_sorted[1:] != ring_sorted[:-1]) + 1
    lo = np.concatenate([[0], bounds])
    hi = np.concatenate([bounds, [len(pts)]])
    x = np.empty(len(pts))
    y = np.empty(len(pts))
    for a, b in zip(lo, hi, strict=True):
        q = pts[a:b]
        sub = q[:: max(1, (b - a) // 256)]
        c = sub.mean(axis=0)
        _, vecs = np.linalg.eigh((sub - c).T @ (sub - c))
        xy = (q - c) @ vecs[:, 1:]
        x[a:b] = xy[:, 1]
        y[a:b] = xy[:, 0]
    return x, y


def estimate_line_noise_2d(x: np.ndarray, y: np.ndarray, run_start: np.ndarray) -> float:
    """:func:`estimate_line_noise` on 2D points (x, y) (M,) (a ring in its scan plane)."""
    m = len(x)
    if m < 15:
        return 0.0
    run_id = np.cumsum(run_start)
    ok = run_id[4:] == run_id[:-4]
    sx = x[1:-3] - 2.0 * x[2:-2] + x[3:-1]
    sy = y[1:-3] - 2.0 * y[2:-2] + y[3:-1]
    dx, dy = x[4:] - x[:-4], y[4:] - y[:-4]
    norm = np.hypot(dx, dy)
    good = ok & (norm > 0)
    if np.count_nonzero(good) < 10:
        return 0.0
    across = np.abs(sx[good] * dy[good] - sy[good] * dx[good]) / norm[good]
    return float(np.median(across) / (0.6745 * np.sqrt(6.0)))


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
    pts = points[order]
    rg = ring[order]
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
    """Moments, directions and lengths of the segments ``[s, e)`` of ``pts``.

    The direction is the principal axis of the scatter, found by power iteration from the
    chord (it converges in two steps for a line: the ratio of its two largest eigenvalues
    is (noise / length)^2); a batched 3x3 eigen-solver costs ~100x more per segment.
    Segments shorter than ``min_length_m``, with fewer than ``min_points`` points or an RMS
    line residual above ``max_rms_m`` are dropped.
    """
    count = e - s
    keep = count >= max(min_points, 2)
    s, e, count = s[keep], e[keep], count[keep]
    if len(s) == 0:
        z = np.zeros(0, dtype=np.int64)
        z3 = np.zeros((0, 3))
        return Segments(
            pts, order, z, z, z, z, z, z3, np.zeros((0, 3, 3)), z3, np.zeros(0), np.zeros(0),
            z3, z3,
        )  # fmt: skip
    idx = ranges(s, e)
    local = np.zeros(len(s), dtype=np.int64)
    np.cumsum(count[:-1], out=local[1:])
    p = pts[idx]
    centroid = np.add.reduceat(p, local, axis=0) / count[:, None]
    q = p - np.repeat(centroid, count, axis=0)
    outer = q[:, _I6] * q[:, _J6]
    m6 = np.add.reduceat(outer, local, axis=0)
    scatter = m6[:, _SYM].reshape(-1, 3, 3)
    v = pts[e - 1] - pts[s]
    for _ in range(3):
        nv = np.linalg.norm(v, axis=1)
        v = v / np.where(nv > 0, nv, 1.0)[:, None]
        v = np.einsum("sij,sj->si", scatter, v)
    nv = np.linalg.norm(v, axis=1)
    direction = v / np.where(nv > 0, nv, 1.0)[:, None]
    lam1 = np.einsum("si,si->s", direction, np.einsum("sij,sj->si", scatter, direction))
    trace = m6[:, 0] + m6[:, 3] + m6[:, 5]
    rms = np.sqrt(np.maximum(trace - lam1, 0.0) / count)
    t0 = np.einsum("ij,ij->i", pts[s] - centroid, direction)
    t1 = np.einsum("ij,ij->i", pts[e - 1] - centroid, direction)
    length = np.abs(t1 - t0)
    ok = (length >= min_length_m) & (nv > 0) & (rms <= max_rms_m)
    sel = np.flatnonzero(ok)
    c = centroid[sel]
    d = direction[sel]
    return Segments(
        points=pts,
        order=order,
        starts=s[sel],
        ends=e[sel],
        ring=ring_sorted[s[sel]].astype(np.int64),
        sweep=sweep_sorted[s[sel]].astype(np.int64),
        count=count[sel],
        centroid=c,
        scatter=scatter[sel],
        direction=d,
        length=length[sel],
        rms=rms[sel],
        end0=c + t0[sel, None] * d,
        end1=c + t1[sel, None] * d,
    )


#: Index pairs of the 6 distinct entries of a symmetric 3x3 matrix, and their layout.
_I6 = np.array([0, 0, 0, 1, 1, 2])
_J6 = np.array([0, 1, 2, 1, 2, 2])
_SYM = np.array([0, 1, 2, 1, 3, 4, 2, 4, 5])
