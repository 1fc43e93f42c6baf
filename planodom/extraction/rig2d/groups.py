"""Segments to planes: traces (:mod:`.traces`), then seeds and greedy growth
(:mod:`.grouping`), in one compiled call per epoch.

:func:`group_segments` passes the segments' arrays once; the linking, the traces'
moments, their direction errors, the grouping and the segments' order by group run in
one kernel (:func:`_group_kernel`), the same kernels in the same order as
:func:`.traces.build_traces` followed by the grouping, without the Python-level calls and
array passes between them.
"""

from __future__ import annotations

import numba
import numpy as np

from planodom.angles import radians
from planodom.extraction.rig2d.grouping import GroupingParams, _grow_kernel
from planodom.extraction.rig2d.segments import Segments
from planodom.extraction.rig2d.traces import (
    LINK_BAND,
    TraceSet,
    _link_segments,
    _LinkParams,
    _SegmentLines,
    _trace_moments,
)


def group_segments(
    segs: Segments,
    params: GroupingParams,
    parallel_deg: float,
    step_m: float,
    seg_times: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[list[np.ndarray], int]:
    """Segments grouped into planes (:mod:`.grouping`).

    Args:
        segs: the epoch's segments.
        params: seeding and growth thresholds.
        parallel_deg, step_m: trace merging (``trace_parallel_deg``, ``trace_step_m``,
            :func:`.traces.build_traces`).
        seg_times: first and last time (s) of each segment, (S,) each, in time windows.

    Returns:
        A list of (K,) int64 arrays of segment indices (increasing), one per plane, and
        the number of seeds rejected after refitting.
    """
    S = len(segs)
    if S < 2:
        return [], 0
    t0s, t1s = (np.zeros(S), np.zeros(S)) if seg_times is None else seg_times
    link = _LinkParams(float(params.tol_m), float(radians(parallel_deg)), float(step_m),
                       float(params.max_span_s), LINK_BAND)  # fmt: skip
    members, bounds, rejected = _group_kernel(
        segs.ring, segs.sweep, np.asarray(t0s, dtype=np.float64),
        np.asarray(t1s, dtype=np.float64), segs.centroid, segs.direction, segs.length,
        segs.count, segs.scatter, segs.end0, segs.end1, float(params.sigma_m), link, params,
    )  # fmt: skip
    groups = [members[bounds[g] : bounds[g + 1]] for g in range(len(bounds) - 1)]
    return groups, int(rejected)


@numba.njit(cache=True)
def _direction_error(sigma_m, count, length):  # pragma: no cover - compiled
    """:func:`.traces.direction_error` of each line, (S,) rad: the same operations in the
    same order, per element."""
    out = np.empty(count.shape[0])
    for i in range(count.shape[0]):
        out[i] = sigma_m * np.sqrt(12.0 / max(count[i], 1)) / max(length[i], 1e-9)
    return out


@numba.njit(cache=True)
def _group_kernel(
    ring, sweep, t0, t1, centroid, direction, length, count, scatter, end0, end1, sigma_m,
    link, p,
):  # fmt: skip  # pragma: no cover - compiled
    """:func:`.traces.build_traces` (linking under ``link``, the traces' moments and
    direction errors) and the grouping (:func:`.grouping._grow_kernel` under ``p``) of the
    segments' arrays (S,) / (S, 3) / (S, 3, 3). Returns the segments of every group,
    concatenated in group order (each group's in increasing index, as a stable argsort by
    group), the bounds (G + 1,) of each group in it and the number of rejected seeds."""
    err = _direction_error(sigma_m, count, length)
    lines = _SegmentLines(ring, sweep, t0, t1, centroid, direction, length, err, count,
                          scatter, end0, end1)  # fmt: skip
    label = _link_segments(lines, link)
    t_ring, cnt, cen, sc, tdir, lo, hi, t_lo, t_hi = _trace_moments(lines, label)
    err_t = _direction_error(sigma_m, cnt, hi - lo)
    tr = TraceSet(label, t_ring, cnt, cen, sc, tdir, lo, hi, err_t, t_lo, t_hi)
    seg_group, n_groups, rejected = _grow_kernel(tr, p)
    bounds = np.zeros(n_groups + 1, dtype=np.int64)
    for i in range(label.shape[0]):
        g = seg_group[label[i]]
        if g >= 0:
            bounds[g + 1] += 1
    for g in range(n_groups):
        bounds[g + 1] += bounds[g]
    members = np.empty(bounds[n_groups], dtype=np.int64)
    fill = bounds[:n_groups].copy()
    for i in range(label.shape[0]):
        g = seg_group[label[i]]
        if g >= 0:
            members[fill[g]] = i
            fill[g] += 1
    return members, bounds, rejected
