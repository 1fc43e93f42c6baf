"""The 2D-rig path without a twist: time windows (the odometry's first epochs).

Without a twist each point is in the base frame of its own time, so traces of successive
sweeps are displaced by the motion between them. When the scan's times spread over more
than ``time_windows.span_s`` (:func:`is_windowed`), the 2D-rig path only combines points
acquired within one window of that span (about one sweep,
:class:`planodom.config.timewindows.TimeWindowConfig`):

- segments merge into a trace only within one sweep and window (:mod:`.traces`);
- two traces seed a plane only when their times lie within the span, a trace joins a
  seed's plane only inside the seed's window, L-shaped seeds are not used
  (:mod:`.grouping`);
- the tolerances grow by the motion within a window (:func:`windowed_tolerances`);
- each wall then gives a plane per window: one is kept (:func:`drop_repeats`), its (n, d)
  extrapolated to the reference time, and only when it was found in ``min_windows``
  windows, or in every sweep when the epoch has fewer (:func:`for_epoch`).

Everything specific to this case is here; the other modules only see a finite
``max_span_s`` and the segment times.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from planodom.config.extraction import ExtractionConfig
from planodom.config.timewindows import TimeWindowConfig
from planodom.extraction.planes.builder import Adjust, PlaneFits
from planodom.extraction.rig2d.scanlines import _angle_reversals
from planodom.extraction.rig2d.segments import Segments
from planodom.extraction.rig2d.window_kernels import compiled_sweep_timing, outline_radii
from planodom.scan import Scan


def is_windowed(scan: Scan, twist: np.ndarray | None, windows: TimeWindowConfig) -> bool:
    """True when the 2D-rig path must work in time windows: no twist, and the scan's
    times spread over more than ``windows.span_s``."""
    if twist is not None or scan.t is None or len(scan.t) == 0:
        return False
    return float(np.ptp(scan.t)) > windows.span_s


@dataclass(frozen=True)
class SweepTiming:
    """The real sweeps of an epoch's scanners (not the runs between no-return gaps):
    ``count`` the most sweeps of one ring, ``period`` (s) the median time between the
    starts of successive sweeps of one ring (inf with one sweep each), ``duration`` (s) the
    longest time span of one sweep (of those shorter than the period, when there are)."""

    count: int
    period: float
    duration: float


def sweep_timing(scan: Scan, segs: Segments) -> SweepTiming:
    """:class:`SweepTiming` of the scan. Sweeps restart where a ring's scan angle jumps
    back (:func:`.scanlines._angle_reversals`): a time gap also opens where the beams see
    nothing (the sky), so the ``sweep`` ids of the segments count too many. One compiled
    pass where it applies (:func:`.window_kernels.compiled_sweep_timing`, the same bits),
    else :func:`numpy_sweep_timing`."""
    if len(segs.order) < 3 or scan.ring is None or scan.t is None:
        return SweepTiming(1, float("inf"), 0.0)
    done = compiled_sweep_timing(scan.ring, scan.t, segs.order, segs.points)
    return numpy_sweep_timing(scan, segs) if done is None else SweepTiming(*done)


def numpy_sweep_timing(scan: Scan, segs: Segments) -> SweepTiming:
    """:func:`sweep_timing` in numpy (a scan with rings and times, three or more
    segment points): the fallback of the compiled pass and the tests' reference."""
    assert scan.ring is not None and scan.t is not None
    ring, t = scan.ring[segs.order], scan.t[segs.order]
    new = np.ones(len(ring), dtype=bool)
    new[1:] = (ring[1:] != ring[:-1]) | _angle_reversals(segs.points, ring.astype(np.int64))
    start, end = t[new], np.maximum.reduceat(t, np.flatnonzero(new))
    sweep_ring = ring[new]
    counts = np.bincount(sweep_ring - sweep_ring.min())
    steps = np.concatenate([np.diff(start[sweep_ring == r]) for r in np.unique(sweep_ring)])
    period = float(np.median(steps)) if len(steps) else float("inf")
    # a "sweep" longer than the period is two whose restart was not seen (a ring that
    # sees only part of its field of view: the jump back is short)
    spans = end - start
    whole = spans[spans < period]
    return SweepTiming(int(counts.max()), period, float(np.max(whole if len(whole) else spans)))


def for_epoch(windows: TimeWindowConfig, scan: Scan, segs: Segments) -> TimeWindowConfig:
    """``windows`` fitted to the epoch's scanners, whose sweeps the defaults assume to be
    those of a 75 Hz LMS (7.5 per 10 Hz epoch, 180 deg in 6.7 ms, one every 13 ms; for it
    nothing changes):

    - ``span_s`` at least one sweep's duration (but below the sweep period, so that a
      window holds one sweep of a ring), and ``motion_m`` grown in proportion: a trace of
      a slower scanner (180 deg at 10 Hz take 50 ms; the ground's trace spans them) never
      fits in a 15 ms window, so it could seed no plane;
    - ``min_windows`` at most the epoch's sweeps per ring (at least 1): a wall is found
      once per sweep, so an epoch of fewer sweeps could never give a plane.
    """
    timing = sweep_timing(scan, segs)
    span = max(windows.span_s, min(1.05 * timing.duration, 0.95 * timing.period))
    n = max(1, timing.count)
    if windows.min_windows <= n and span == windows.span_s:
        return windows
    update = {"span_s": span, "motion_m": windows.motion_m * span / windows.span_s,
              "min_windows": min(windows.min_windows, n)}  # fmt: skip
    return windows.model_copy(update=update)


def per_window(config: ExtractionConfig, windows: TimeWindowConfig) -> ExtractionConfig:
    """``config`` with the plane minimum of one window: with
    ``windows.min_points_over_windows``, ``min_plane_points`` divided among the
    ``windows.min_windows`` windows a plane must be found in (rounded up, at least 3), so
    that those windows hold ``min_plane_points`` between them; else ``config`` itself.
    ``windows``: the epoch's (:func:`for_epoch`)."""
    if not windows.min_points_over_windows:
        return config
    share = max(3, -(-config.min_plane_points // max(1, windows.min_windows)))
    return config.model_copy(update={"min_plane_points": share})


def segment_times(scan: Scan, segs: Segments) -> tuple[np.ndarray, np.ndarray]:
    """First and last acquisition time (s) of every segment, (S,) each (scan with times)."""
    assert scan.t is not None  # the time-window path runs only on scans with times
    tt = scan.t[segs.order]
    return tt[segs.starts], tt[segs.ends - 1]


def windowed_tolerances(
    tol_m: float, max_rms_m: float, seed_floor_m: float, windows: TimeWindowConfig
) -> tuple[float, float, float]:
    """The member tolerance, RMS limit and seed floor (m) widened by the motion within a
    window: ``motion_m`` on the tolerance and the floor, half of it on the RMS limit."""
    return widened(tol_m, max_rms_m, seed_floor_m, windows.motion_m)


def widened(
    tol_m: float, max_rms_m: float, seed_floor_m: float, motion_m: float
) -> tuple[float, float, float]:
    """The member tolerance, RMS limit and seed floor (m) widened by a smear of the points
    about their plane of ``motion_m`` (m): all of it on the tolerance and the floor, half
    of it on the RMS limit (a smear spread evenly over +-m has an RMS of m / sqrt(3))."""
    return tol_m + motion_m, max_rms_m + 0.5 * motion_m, seed_floor_m + motion_m


def twist_smear(scan: Scan, points: np.ndarray, rate_rad_s: float, speed_m_s: float) -> float:
    """The smear (m) about their plane of the points of one wall deskewed with a twist off
    by ``rate_rad_s`` and ``speed_m_s``: a point acquired ``t`` after the reference time
    moves by about ``(speed + rate * range) t``, linear in time, so over the epoch's time
    span a plane fit to the wall's points leaves them within half of it either side. The
    range is the median of the points' (``points`` (N, 3) m): walls at all ranges count."""
    if scan.t is None or len(scan.t) == 0 or (rate_rad_s == 0 and speed_m_s == 0):
        return 0.0
    # writeable and C-contiguous: a read-only array would compile a second specialisation
    rng = float(median_range(np.require(points, np.float64, ("C", "W"))))
    return 0.5 * float(np.ptp(scan.t)) * (speed_m_s + rate_rad_s * rng)


@numba.njit(cache=True)
def median_range(points):  # pragma: no cover - compiled
    """``np.median(np.linalg.norm(points, axis=1))`` of points (N, 3), N >= 1, metres,
    with the same bits (a sum of the three squares in order, then the median), in one
    compiled pass: numpy's reduction along the short axis cost ~1 ms on a 2D-rig epoch's
    points, a quarter of its extraction."""
    n = points.shape[0]
    r = np.empty(n)
    for i in range(n):
        p0, p1, p2 = points[i, 0], points[i, 1], points[i, 2]
        r[i] = np.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
    return np.median(r)


def keep_one_per_wall(
    fits: PlaneFits,
    points: np.ndarray,
    scan: Scan,
    tol_m: float,
    windows: TimeWindowConfig,
    allowed: np.ndarray | None = None,
) -> Adjust:
    """The builder's ``adjust`` step (:func:`planodom.extraction.planes.builder.build_planes`)
    for time windows: :func:`drop_repeats` on the kept planes, with each plane's mean
    inlier time and support radius (the farthest outline point from its centroid: the
    polygon's vertices are among them). ``points`` (N, 3) m: the scan's points.
    ``allowed`` (G,) bool: when given, only these fits are kept and count as a wall's
    windows (:func:`.sparsewindows.determined`)."""

    def adjust(kept: np.ndarray, n_or: np.ndarray, d_or: np.ndarray) -> np.ndarray:
        if allowed is not None:
            kept = kept[allowed[kept]]
            if not len(kept):
                return kept
        cnt = np.maximum(fits.count, 1).astype(np.float64)
        assert scan.t is not None
        tm = np.add.reduceat(scan.t[fits.inliers], fits.bounds[:-1]) / cnt
        rad = support_radii(fits, points)
        sel, n_k, d_k = drop_repeats(
            n_or[kept], d_or[kept], fits.centroid[kept], rad[kept], tm[kept], tol_m, windows
        )
        kept = kept[sel]
        n_or[kept], d_or[kept] = n_k, d_k
        return kept

    return adjust


def support_radii(fits: PlaneFits, points: np.ndarray) -> np.ndarray:
    """(G,) each fit's support radius (m): the farthest of its outline inliers from its
    centroid (0 without any), of the scan's ``points`` (N, 3) m; one compiled pass
    (:func:`.window_kernels.outline_radii`, the same bits) for float64 points and
    centroids, else :func:`numpy_support_radii`."""
    if points.dtype != np.float64 or fits.centroid.dtype != np.float64:
        return numpy_support_radii(fits, points)
    return outline_radii(
        points, fits.inliers.astype(np.int64, copy=False),
        fits.bounds.astype(np.int64, copy=False), fits.outline.astype(bool, copy=False),
        np.ascontiguousarray(fits.centroid),
    )  # fmt: skip


def numpy_support_radii(fits: PlaneFits, points: np.ndarray) -> np.ndarray:
    """:func:`support_radii` in numpy: the fallback and the tests' reference."""
    G = len(fits)
    gid = np.repeat(np.arange(G), np.diff(fits.bounds))[fits.outline]
    r_end = np.linalg.norm(points[fits.inliers[fits.outline]] - fits.centroid[gid], axis=1)
    rad = np.zeros(G)
    np.maximum.at(rad, gid, r_end)
    return rad


def drop_repeats(
    n: np.ndarray,
    d: np.ndarray,
    cen: np.ndarray,
    rad: np.ndarray,
    tm: np.ndarray,
    tol_m: float,
    windows: TimeWindowConfig,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Keep one plane per wall among planes fit in different time windows (no deskew).

    Planes are visited by the mean time of their inliers, earliest first (closest to the
    reference time, so least displaced by the motion); a plane is dropped when a kept one
    has its normal within ``repeat_deg`` (either sign), its offset within
    ``tol_m + speed_m_s * dt`` (dt: the difference of their mean times) and
    supports that overlap (bounding circles about the centroids, grown by the same
    allowance). A plane found in fewer than ``min_windows`` windows is dropped.
    The (n, d) of a kept plane are extrapolated to the reference time t = 0 from its
    repeats: a straight-line fit of each normal component and of the offset against the
    windows' mean times (constant velocity), normal renormalised and oriented as before.

    Args:
        n: (P, 3) oriented unit normals. d: (P,) offsets (m). cen: (P, 3) support centroids
        (m). rad: (P,) support radii about them (m). tm: (P,) mean inlier times (s).

    Returns:
        Indices (K,) of the kept planes (ascending), their normals (K, 3) and offsets (K,).
    """
    P = len(n)
    if P < 2:
        keep = np.arange(P) if windows.min_windows <= 1 else np.zeros(0, np.int64)
        return keep, n[keep], d[keep]
    order = np.argsort(tm, kind="stable")
    cos_tol = np.cos(np.radians(windows.repeat_deg))
    c = n @ n.T
    sgn = np.where(c < 0, -1.0, 1.0)
    allow = tol_m + windows.speed_m_s * np.abs(tm[:, None] - tm[None, :])
    same = (np.abs(c) >= cos_tol) & (np.abs(sgn * d[:, None] - d[None, :]) <= allow)
    dist = np.linalg.norm(cen[:, None] - cen[None, :], axis=2)
    same &= dist <= rad[:, None] + rad[None, :] + allow
    np.fill_diagonal(same, False)
    seen = same.sum(axis=1)
    kept: list[int] = []
    for i in order:
        if seen[i] + 1 < windows.min_windows:
            continue
        if not (kept and np.any(same[i, kept])):
            kept.append(int(i))
    kept.sort()
    keep = np.array(kept, dtype=np.int64)
    n_out, d_out = n[keep].copy(), d[keep].copy()
    for k, i in enumerate(keep):
        idx = np.concatenate([[i], np.flatnonzero(same[i])])
        t = tm[idx]
        if len(idx) < 2 or np.ptp(t) <= 0:
            continue
        # Least-squares line y = a + b t per component; a is the value at t = 0.
        y = sgn[i, idx][:, None] * np.column_stack([n[idx], d[idx]])  # (K, 4)
        tc = t - t.mean()
        slope = tc @ (y - y.mean(axis=0)) / (tc @ tc)
        at0 = y.mean(axis=0) - slope * t.mean()
        norm = float(np.linalg.norm(at0[:3]))
        if not norm > 0:
            continue
        s = 1.0 if at0[:3] @ n[i] >= 0 else -1.0  # the plane's own orientation
        n_out[k] = s * at0[:3] / norm
        d_out[k] = s * at0[3] / norm
    return keep, n_out, d_out
