"""Straight segments of the scan lines of a 2D-scanner rig, with their moments.

The scan lines are cut into runs and the runs split into straight pieces
(:mod:`.scanlines`); each piece is then described by exact 3D moments of its (deskewed)
points (:class:`Segments`): count, centroid, centred scatter, direction (principal axis),
length, RMS line residual and end points. A corner point at an end is trimmed, and a piece
whose 3D line residual exceeds the split tolerance (a ring that is not planar), that is
too short or has too few points is dropped. The moments are compiled with numba (one pass
over the points of each piece).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction.kernels import range_moments
from planodom.extraction.memo import identity_memo, read_only
from planodom.extraction.rig2d.rangenoise import estimate_range_noise_2d
from planodom.extraction.rig2d.scanlines import (
    _angle_reversals,
    _breaks_kernel,
    beam_timing,
    estimate_line_noise_2d,
    ring_plane_coordinates,
    split_runs,
)
from planodom.extraction.scan_prep import compiled_ring_order

#: The kernel's ``origins`` when there are none (numba needs an array of one type).
_NO_ORIGINS = np.zeros((1, 3))
#: End points a segment may lose to :func:`_features_kernel`'s trimming, per segment.
MAX_END_TRIM = 3


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


@identity_memo
def ring_order(
    ring: np.ndarray, t: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, tuple[float, bool]]:
    """What :func:`split_scan_lines` needs of a scan's ``ring`` (N,) and ``t`` (N,) s or
    None, which do not change when the scan is deskewed again with another twist
    (memoised, :mod:`planodom.extraction.memo`): the stable order by ring (N,) int64, the
    rings (int64) and times in that order, and :func:`.scanlines.beam_timing`; in one
    compiled call (:func:`planodom.extraction.scan_prep.compiled_ring_order`, the same
    bits) where it applies, else :func:`numpy_ring_order`."""
    done = compiled_ring_order(ring, t)
    if done is None:
        return numpy_ring_order(ring, t)
    order, rg, tt, timing = done
    frozen = tuple(read_only(a) for a in (order, rg) + (() if tt is None else (tt,)))
    return frozen[0], frozen[1], (None if tt is None else frozen[2]), timing


def numpy_ring_order(
    ring: np.ndarray, t: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, tuple[float, bool]]:
    """:func:`ring_order` in numpy (not memoised): the fallback of the compiled call and
    the tests' reference."""
    if len(ring) > 1 and np.any(ring[1:] < ring[:-1]):
        key = ring - ring.min()
        # A stable radix sort on small integer keys is ~10x faster than on int64.
        key = key.astype(np.uint16) if key.max() < 65536 else key
        order = np.argsort(key, kind="stable")
    else:
        order = np.arange(len(ring))
    rg = np.take(ring, order).astype(np.int64)
    tt = None if t is None else np.take(t, order)
    timing = beam_timing(rg, tt)
    frozen = tuple(read_only(a) for a in (order, rg) + (() if tt is None else (tt,)))
    return frozen[0], frozen[1], (None if tt is None else frozen[2]), timing


def split_scan_lines(
    points: np.ndarray, ring: np.ndarray, t: np.ndarray | None, config: ExtractionConfig,
    origins: np.ndarray | None = None,
) -> tuple[Segments, float]:  # fmt: skip
    """Straight segments of every ring of a 2D-rig epoch.

    Args:
        points: (N, 3) metres, finite (already deskewed when a twist is known).
        ring: (N,) scanner id of each point; points of one ring in scan order.
        t: (N,) seconds or None, used to find sweep boundaries.
        origins: (R, 3) the sensor origin of each ring id (m, base frame; one row: one for
            all) or None; with ``config.noise_estimate: range`` the noise is estimated
            along the rays (:mod:`.rangenoise`), else (or without origins) across the lines.
        config: thresholds (``sweep_gap_factor``, ``min_gap_m``, ``gap_range_ratio``,
            ``split_sigma_factor``, ``min_segment_length_m``). Segments of two points are
            kept: one sweep may put only two beams on a narrow or distant wall, and
            :mod:`.grouping` merges them over sweeps before ``min_segment_points`` applies.

    Returns:
        The kept :class:`Segments` and the effective noise sigma (m) used for the
        tolerances (:func:`planodom.extraction.noise.effective_noise`).
    """
    fields = (config.sweep_gap_factor, config.min_gap_m, config.gap_range_ratio,
              config.estimate_noise, config.range_noise_m, config.split_sigma_factor,
              config.tolerance_floor_m, config.min_segment_length_m)  # fmt: skip
    if config.noise_estimate == "range" and origins is not None:
        return _split(points, np.asarray(ring), t, fields, np.asarray(origins, dtype=np.float64))
    return _split(points, np.asarray(ring), t, fields)


@identity_memo
def _split(
    points: np.ndarray, ring: np.ndarray, t: np.ndarray | None, fields: tuple,
    origins: np.ndarray | None = None,
) -> tuple[Segments, float]:  # fmt: skip
    """:func:`split_scan_lines` with the config ``fields`` it reads, memoised
    (:mod:`planodom.extraction.memo`): an epoch lost with its tolerances is extracted
    again with the same deskewed points and only the grouping's tolerances widened
    (:func:`planodom.odometry.twist_sigma.widened_if_lost`). The segments' arrays are
    read-only: they are shared. ``origins`` (R, 3): the noise along the rays
    (:mod:`.rangenoise`); None: across the lines."""
    sweep_gap, min_gap, gap_ratio, estimate_noise, range_noise, split_factor, floor, min_len = (
        fields
    )
    order, rg, tt, timing = ring_order(ring, t)
    has_t = tt is not None
    tt = np.ascontiguousarray(tt, dtype=np.float64) if has_t else np.zeros(len(order))
    (pts, s, e, seg_ring, sweep, cen, sc, direction, length, rms, end0, end1, sigma) = (
        _split_kernel(
            np.asarray(points, dtype=np.float64), order, rg, tt, has_t, timing[0], timing[1],
            float(sweep_gap), float(min_gap), float(gap_ratio), bool(estimate_noise),
            float(range_noise), float(split_factor), float(floor), float(min_len), MAX_END_TRIM,
            origins is not None, _NO_ORIGINS if origins is None else origins,
        )
    )  # fmt: skip
    segs = Segments(
        points=pts, order=order, starts=s, ends=e, ring=seg_ring, sweep=sweep, count=e - s,
        centroid=cen, scatter=sc, direction=direction, length=length, rms=rms, end0=end0,
        end1=end1,
    )  # fmt: skip
    for a in vars(segs).values():
        read_only(a)
    return segs, float(sigma)


@numba.njit(cache=True)
def _split_kernel(
    points, order, rg, tt, has_t, med, any_forward, sweep_gap, min_gap, gap_ratio,
    estimate_noise, range_noise, split_factor, floor, min_len, max_trim, along_rays, origins,
):  # fmt: skip  # pragma: no cover - compiled
    """:func:`_split` in one compiled call: the points in ring order (``order`` (N,),
    rings ``rg`` (N,) int64, times ``tt`` (N,) s, zeros without ``has_t``), the runs
    (:func:`.scanlines.run_breaks` with the timing ``med``, ``any_forward`` of
    :func:`.scanlines.beam_timing`), the 2D coordinates, the noise sigma
    (:func:`planodom.extraction.noise.noise_sigma`; ``along_rays``: from the range noise
    of :mod:`.rangenoise` with ``origins`` (R, 3)), the split and
    :func:`segment_features` (at least 2 points, RMS within the split tolerance): the
    same kernels in the same order as their Python-level sequence, without the calls
    between them. Returns the ring-ordered points (N, 3), the kept segments' starts,
    ends, rings, sweeps, centroids, scatters, directions, lengths, RMS, end points and the
    sigma (m)."""
    pts = gather_rows(points, order)
    m = pts.shape[0]
    run_start, sweep_start = _breaks_kernel(pts, rg, tt, has_t, med, sweep_gap, min_gap, gap_ratio)
    if m > 1 and not any_forward:
        rev = _angle_reversals(pts, rg)
        for i in range(m - 1):
            if rev[i]:
                sweep_start[i + 1] = True
                run_start[i + 1] = True
    x, y = ring_plane_coordinates(pts, rg)
    estimate = 0.0
    if estimate_noise and along_rays:
        estimate = estimate_range_noise_2d(x, y, pts, rg, origins, run_start)
    elif estimate_noise:
        estimate = estimate_line_noise_2d(x, y, run_start)
    sigma = max(range_noise, estimate) if estimate_noise else range_noise
    split_tol = max(split_factor * sigma, floor)
    starts = np.flatnonzero(run_start)
    ends = np.empty(starts.shape[0], dtype=np.int64)
    ends[:-1] = starts[1:]
    if m > 0:
        ends[-1] = m
    s0, e0 = split_runs(x, y, starts, ends, split_tol)
    s, e, cen, sc, dirs, length, rms, t0, t1 = _features_kernel(
        pts, s0, e0, 2, min_len, split_tol, max_trim
    )
    n = s.shape[0]
    seg_ring = np.empty(n, dtype=np.int64)
    sweep = np.empty(n, dtype=np.int64)
    end0 = np.empty((n, 3))
    end1 = np.empty((n, 3))
    k = 0
    cum = -1  # np.cumsum(sweep_start) - 1 at the segments' starts (in order)
    for i in range(m):
        cum += sweep_start[i]
        while k < n and s[k] == i:
            seg_ring[k] = rg[i]
            sweep[k] = cum
            k += 1
    for k in range(n):
        for u in range(3):
            end0[k, u] = cen[k, u] + t0[k] * dirs[k, u]
            end1[k, u] = cen[k, u] + t1[k] * dirs[k, u]
    return pts, s, e, seg_ring, sweep, cen, sc, dirs, length, rms, end0, end1, sigma


@numba.njit(cache=True)
def gather_rows(points, order):  # pragma: no cover - compiled
    """``points[order]`` of points (N, 3) and indices (M,) int64 in [0, N), a new (M, 3)
    array: one compiled pass, a third of ``np.take``'s time on an epoch's points."""
    out = np.empty((order.shape[0], 3))
    for k in range(order.shape[0]):
        i = order[k]
        out[k, 0], out[k, 1], out[k, 2] = points[i, 0], points[i, 1], points[i, 2]
    return out


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
