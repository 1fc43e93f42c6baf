"""The time windows' per-epoch passes in compiled calls (:mod:`.windows`).

An epoch extracted without a twist (:func:`.windows.is_windowed`) fits its windows to
the scanners' sweeps (:func:`.windows.sweep_timing`) and keeps one plane per wall
(:func:`.windows.keep_one_per_wall`). Both began with some ten numpy calls over the
epoch's points each (gathers by ring order, reductions by sweep, one array per ring,
``ufunc.at``), 0.2-0.4 ms an epoch on the 2D-rig worlds at 2 cm, where more steps are
extracted without a twist. Each is one compiled pass here, with the same bits: selections,
integer counts, comparisons, maxima and the same float operations in the same order
(a median is an order statistic; a norm's squares are summed left to right, as numpy's
reduction along a row of three). What these kernels do not take (a scan out of ring
order, times that are not float64) stays with numpy.
"""

from __future__ import annotations

import numba
import numpy as np

from planodom.extraction.rig2d.scanlines import _angle_reversals


def compiled_sweep_timing(
    ring: np.ndarray, t: np.ndarray, order: np.ndarray, points: np.ndarray
) -> tuple[int, float, float] | None:
    """(count, period, duration) of :func:`.windows.sweep_timing` for a scan's ``ring``
    (N,) and ``t`` (N,) s, the segments' ring ``order`` (M,) int64 (M >= 3) and their
    ring-ordered ``points`` (M, 3) m; None where numpy decides (times not float64, rings
    not in order)."""
    if t.dtype != np.float64 or order.dtype != np.int64:
        return None
    ok, count, period, duration = _sweep_timing_kernel(
        np.ascontiguousarray(ring, dtype=np.int64), np.ascontiguousarray(t), order, points
    )
    return (int(count), float(period), float(duration)) if ok else None


@numba.njit(cache=True)
def _sweep_timing_kernel(ring, t, order, points):  # pragma: no cover - compiled
    """:func:`.windows.numpy_sweep_timing` in one pass: ``(ok, count, period, duration)``,
    ``ok`` False when the rings in ``order`` are not ascending (then nothing else is
    computed). A sweep begins where the ring changes or its scan angle jumps back
    (:func:`.scanlines._angle_reversals`); its start is its first time, its end the
    largest; the period is the median of the steps between the starts of a ring's
    successive sweeps (inf without any), the duration the longest span of a sweep
    shorter than the period (of all, when none is)."""
    m = order.shape[0]
    rg = np.empty(m, dtype=np.int64)
    tt = np.empty(m)
    for k in range(m):
        rg[k] = ring[order[k]]
        tt[k] = t[order[k]]
    for k in range(1, m):
        if rg[k] < rg[k - 1]:
            return False, 0, 0.0, 0.0
    rev = _angle_reversals(points, rg)
    n_sweeps = 1
    for k in range(1, m):
        if rg[k] != rg[k - 1] or rev[k - 1]:
            n_sweeps += 1
    start = np.empty(n_sweeps)
    end = np.empty(n_sweeps)
    sweep_ring = np.empty(n_sweeps, dtype=np.int64)
    s = 0
    start[0], end[0], sweep_ring[0] = tt[0], tt[0], rg[0]
    for k in range(1, m):
        if rg[k] != rg[k - 1] or rev[k - 1]:
            s += 1
            start[s], end[s], sweep_ring[s] = tt[k], tt[k], rg[k]
        elif not (end[s] >= tt[k] or end[s] != end[s]):  # np.maximum: the first of
            end[s] = tt[k]  # equals, NaN propagated
    # sweeps of one ring are consecutive (rings ascending): their counts and steps
    count, run = 1, 1
    steps = np.empty(n_sweeps)
    n_steps = 0
    for s in range(1, n_sweeps):
        if sweep_ring[s] == sweep_ring[s - 1]:
            run += 1
            steps[n_steps] = start[s] - start[s - 1]
            n_steps += 1
        else:
            run = 1
        count = max(count, run)
    period = np.median(steps[:n_steps]) if n_steps else np.inf
    spans = end - start
    duration = -np.inf
    any_whole = False
    for s in range(n_sweeps):
        if spans[s] < period:
            any_whole = True
            duration = _nan_max(duration, spans[s])
    if not any_whole:
        for s in range(n_sweeps):
            duration = _nan_max(duration, spans[s])
    return True, count, period, duration


@numba.njit(cache=True)
def _nan_max(a, b):  # pragma: no cover - compiled
    """``np.max``'s pairwise step: ``a`` unless ``b`` is larger or NaN (``a`` NaN stays)."""
    if a != a:
        return a
    return b if (b > a or b != b) else a


@numba.njit(cache=True)
def outline_radii(points, inliers, bounds, outline, centroid):  # pragma: no cover - compiled
    """(G,) each fit's support radius: the largest distance (m) from its centroid
    ``centroid`` (G, 3) to its outline inliers (``inliers`` (K,) int64 indices of
    ``points`` (N, 3), fit g's ``inliers[bounds[g]:bounds[g + 1]]``, ``outline`` (K,)
    bool), 0 without any: ``np.maximum.at`` of ``np.linalg.norm(..., axis=1)`` into zeros
    (a row's squares summed left to right, NaN propagated)."""
    G = bounds.shape[0] - 1
    rad = np.zeros(G)
    for g in range(G):
        for k in range(bounds[g], bounds[g + 1]):
            if outline[k]:
                i = inliers[k]
                d0 = points[i, 0] - centroid[g, 0]
                d1 = points[i, 1] - centroid[g, 1]
                d2 = points[i, 2] - centroid[g, 2]
                r = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                if not rad[g] >= r:  # np.maximum: the first of equals, NaN propagated
                    if rad[g] == rad[g] or r != r:
                        rad[g] = r
    return rad
