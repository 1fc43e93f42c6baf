"""Cut the scan lines of a 2D-scanner rig into runs, and runs into straight pieces.

A ring (one scanner) holds, within one epoch, several successive sweeps. Its points, kept
in scan order, are first cut into runs (:func:`run_breaks`):

- at a change of ring;
- at a sweep boundary: the time step to the next point exceeds ``sweep_gap_factor`` times
  the median beam interval, or time goes backwards (without times: the scan angle jumps
  back);
- at a spatial gap larger than ``max(min_gap_m, gap_range_ratio * range)``.

Each run is then split recursively at the point farthest from the chord joining its end
points while that distance exceeds the split tolerance (iterative end-point fit, the
"split" of split-and-merge, :func:`split_runs`).

The split runs in 2D: each ring's points are projected on the ring's best-fit plane (its
scan plane, up to the motion left after deskewing, :func:`ring_plane_coordinates`), where
range noise lies entirely, so a chord distance costs two products instead of a 3D cross
product; the noise across the lines is estimated there too
(:func:`estimate_line_noise_2d`).

The passes over the points are compiled with numba: they are short loops with branches
over ~10^4 points per epoch, where numpy needs tens of array passes and temporaries each;
no library implements split-and-merge.
"""

from __future__ import annotations

import numba
import numpy as np

from planodom.extraction.kernels import add_outer, median_nonnegative, range_moments


def run_breaks(
    points: np.ndarray,
    ring: np.ndarray,
    t: np.ndarray | None,
    sweep_gap_factor: float,
    min_gap_m: float,
    gap_range_ratio: float,
    timing: tuple[float, bool] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Where runs start, for points sorted by ring in scan order.

    Args:
        points: (M, 3) metres. ring: (M,) ids. t: (M,) seconds or None.
        timing: ``beam_timing(ring, t)`` when already known (it does not depend on the
            points).

    Returns:
        ``run_start`` (M,) bool, True where a run starts (always at 0), and
        ``sweep_start`` (M,) bool, True where a sweep (or ring) starts.
    """
    pts = np.ascontiguousarray(points, dtype=np.float64)
    rg = np.ascontiguousarray(ring, dtype=np.int64)
    has_t = t is not None
    tt = np.ascontiguousarray(t, dtype=np.float64) if has_t else np.zeros(len(pts))
    med, any_forward = _timing_kernel(rg, tt, has_t) if timing is None else timing
    run_start, sweep_start = _breaks_kernel(
        pts, rg, tt, has_t, med, sweep_gap_factor, min_gap_m, gap_range_ratio
    )
    if len(pts) > 1 and not any_forward:
        rev = _angle_reversals(pts, rg)
        sweep_start[1:] |= rev
        run_start[1:] |= rev
    return run_start, sweep_start


def beam_timing(ring: np.ndarray, t: np.ndarray | None) -> tuple[float, bool]:
    """The median beam interval (s; 0: unknown) of points sorted by ring in scan order,
    ``ring`` (M,) ids and ``t`` (M,) seconds or None, and whether time ever moves forward
    (what :func:`run_breaks` needs of the times)."""
    rg = np.ascontiguousarray(ring, dtype=np.int64)
    has_t = t is not None
    tt = np.ascontiguousarray(t, dtype=np.float64) if has_t else np.zeros(len(rg))
    med, any_forward = _timing_kernel(rg, tt, has_t)
    return float(med), bool(any_forward)


@numba.njit(cache=True)
def _timing_kernel(ring, t, has_t):  # pragma: no cover - compiled
    """:func:`beam_timing`: the median of the positive time steps within a ring (0.0 when
    none) and whether any time step is positive."""
    m = ring.shape[0]
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
    return med, any_forward


@numba.njit(cache=True)
def _breaks_kernel(pts, ring, t, has_t, med, sweep_gap_factor, min_gap_m, gap_range_ratio):
    """:func:`run_breaks` without the angle test, given the median beam interval."""
    m = pts.shape[0]
    run_start = np.ones(m, dtype=np.bool_)
    sweep_start = np.ones(m, dtype=np.bool_)
    for i in range(1, m):
        new = ring[i] != ring[i - 1]
        if has_t:
            dt = t[i] - t[i - 1]
            new = new or dt < 0 or (med > 0 and dt > sweep_gap_factor * med)
        sweep_start[i] = new
        if new:
            continue  # run_start[i] is True already
        d0 = pts[i, 0] - pts[i - 1, 0]
        d1 = pts[i, 1] - pts[i - 1, 1]
        d2 = pts[i, 2] - pts[i - 1, 2]
        step = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        # the range only where it can decide: a step within min_gap_m is never a gap
        gap = step > min_gap_m
        if gap:
            rng = np.sqrt(pts[i, 0] ** 2 + pts[i, 1] ** 2 + pts[i, 2] ** 2)
            gap = step > max(min_gap_m, gap_range_ratio * rng)
        run_start[i] = gap
    return run_start, sweep_start


@numba.njit(cache=True)
def _angle_reversals(points, ring):  # pragma: no cover - compiled
    """(M - 1,) bool: where a ring's sweep restarts: its scan angle jumps back by more
    than 60 deg, or has turned by more than 300 deg since the sweep began.

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
            turned = 0.0  # scan angle swept since the sweep began
            for k in range(b - a - 1):
                s = sign * step[k]
                turned += s
                # a reversal, or a full turn: a scanner whose mirror turns on (field of
                # view above 240 deg) starts a sweep with a jump forward over its blind
                # sector, the start angle passed again
                if s < -lim or turned > 2.0 * np.pi - lim:
                    out[a + k] = True
                    turned = 0.0
        a = b
    return out


@numba.njit(cache=True)
def split_runs(x, y, starts, ends, tol):  # pragma: no cover - compiled
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
        # scalar sums (no per-sample row arrays: those cost as much as the projection
        # below); the same operations in the same order as a row-wise sum
        c0 = c1 = c2 = 0.0
        ns = 0
        for i in range(a, b, step):
            c0 += pts[i, 0]
            c1 += pts[i, 1]
            c2 += pts[i, 2]
            ns += 1
        c = np.array([c0 / ns, c1 / ns, c2 / ns])
        sc = np.zeros((3, 3))
        for i in range(a, b, step):
            q0, q1, q2 = pts[i, 0] - c[0], pts[i, 1] - c[1], pts[i, 2] - c[2]
            add_outer(sc, q0, q1, q2)
        sc[1, 0], sc[2, 0], sc[2, 1] = sc[0, 1], sc[0, 2], sc[1, 2]
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
    none = np.empty((0, 3))
    return noise_sigma_2d(x, y, run_start, none, np.empty(0, np.int64), none, False)


@numba.njit(cache=True)
def noise_sigma_2d(x, y, run_start, pts, ring_sorted, origins, along_rays):  # pragma: no cover
    """The noise sigma (m) from the second differences ``p[c-1] - 2 p[c] + p[c+1]`` across
    the chords ``p[c+2] - p[c-2]`` of 2D points (x, y) (M,) in runs (``run_start`` (M,)
    bool): across the lines, or with ``along_rays`` each divided by the sine of the angle
    between the ray and the line (:mod:`.rangenoise`: ``pts`` (M, 3) m, ``ring_sorted`` (M,)
    int64, ``origins`` (R, 3) m, one row: one for all), then their robust median. 0.0 with
    fewer than 15 points or fewer than 10 usable second differences."""
    m = x.shape[0]
    if m < 15:
        return 0.0
    values = np.empty(m)
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
        across = abs(sx * dy - sy * dx) / norm
        if along_rays:
            sin_a = _ray_line_sine(pts, c, origins[ring_sorted[c] if origins.shape[0] > 1 else 0])
            if not sin_a > 0:
                continue
            across = across / sin_a
        values[k] = across
        k += 1
    if k < 10:
        return 0.0
    return median_nonnegative(values, k) / (0.6745 * np.sqrt(6.0))


@numba.njit(cache=True)
def _ray_line_sine(pts, c, o):  # pragma: no cover - compiled
    """The sine of the angle between the ray from ``o`` (3,) m to point ``c`` of ``pts``
    (M, 3) m and the chord ``pts[c+2] - pts[c-2]`` (0.0 when either is zero)."""
    r0, r1, r2 = pts[c, 0] - o[0], pts[c, 1] - o[1], pts[c, 2] - o[2]
    d0 = pts[c + 2, 0] - pts[c - 2, 0]
    d1 = pts[c + 2, 1] - pts[c - 2, 1]
    d2 = pts[c + 2, 2] - pts[c - 2, 2]
    c0, c1, c2 = r1 * d2 - r2 * d1, r2 * d0 - r0 * d2, r0 * d1 - r1 * d0
    rd = np.sqrt((r0 * r0 + r1 * r1 + r2 * r2) * (d0 * d0 + d1 * d1 + d2 * d2))
    return np.sqrt(c0 * c0 + c1 * c1 + c2 * c2) / rd if rd > 0 else 0.0
