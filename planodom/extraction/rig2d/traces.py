"""Traces: the straight segments of one scanner on one wall, merged over the sweeps.

A scanner sweeps several times per epoch; its segments on one wall in successive sweeps
are parallel lines displaced by the vehicle's motion (identical when it stands still).
Segments of one ring in consecutive sweeps are linked when they are parallel (within
``trace_parallel_deg`` plus three times their predicted direction errors), the centroid of
one lies within ``tol + trace_step_m`` of the other's line and their extents along it
overlap; linked components are *traces*. A trace's moments are the sums of its segments'
(parallel-axis theorem), its direction the mean of theirs weighted by their inverse
predicted variances (``N L^2``). This is the "trace" of
:mod:`planodom.simulation.observability`, and it keeps the few points each sweep puts on a
narrow wall together (direction known from all sweeps).

In time windows (points not deskewed, ``max_span_s`` finite, :mod:`.windows`) segments
merge only within one sweep and one window.

The linking is compiled with numba: a loop over a few hundred segments with per-pair
decisions and a union-find, where numpy pays its per-call overhead for every pair.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from planodom.extraction.kernels import find_root, root_labels
from planodom.extraction.rig2d.segments import Segments

#: Segments after each one (same ring, in time order) searched for its continuation in
#: later sweeps: about 4 sweeps of ~8 segments each.
LINK_BAND = 32


class TraceSet(NamedTuple):
    """The traces of one epoch (module docstring); a named tuple, so that the compiled
    grouping kernels take it as one argument.

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
    count: np.ndarray  # type: ignore[assignment]  # shadows tuple.count; numba reads it by name
    centroid: np.ndarray
    scatter: np.ndarray
    direction: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    dir_err: np.ndarray
    t_lo: np.ndarray
    t_hi: np.ndarray


class _SegmentLines(NamedTuple):
    """The segments as the compiled linking reads them (:class:`.segments.Segments`):
    which ring, sweep and times (t0, t1 (S,) s) they belong to; their lines, with the
    predicted direction errors err (S,) rad; their moments; their end points."""

    ring: np.ndarray
    sweep: np.ndarray
    t0: np.ndarray
    t1: np.ndarray
    centroid: np.ndarray
    direction: np.ndarray
    length: np.ndarray
    err: np.ndarray
    count: np.ndarray  # type: ignore[assignment]  # shadows tuple.count; numba reads it by name
    scatter: np.ndarray
    end0: np.ndarray
    end1: np.ndarray


class _LinkParams(NamedTuple):
    """Linking thresholds: member tolerance (m), parallel angle (rad), step between
    sweeps (m), longest time span (s; inf: no windows), segments searched after each."""

    tol_m: float
    parallel_rad: float
    step_m: float
    max_span_s: float
    band: int


def direction_error(sigma_m: float, count: np.ndarray, length: np.ndarray) -> np.ndarray:
    """Predicted 1-sigma direction error (rad) of a line fit to ``count`` points spread
    over ``length`` m with noise ``sigma_m``: ``sigma sqrt(12 / N) / length``."""
    return sigma_m * np.sqrt(12.0 / np.maximum(count, 1)) / np.maximum(length, 1e-9)


def build_traces(
    segs: Segments,
    tol_m: float,
    sigma_m: float,
    parallel_deg: float,
    step_m: float,
    seg_times: tuple[np.ndarray, np.ndarray] | None = None,
    max_span_s: float = np.inf,
) -> TraceSet:
    """Merge the segments of each ring over its sweeps into a :class:`TraceSet`.

    ``seg_times``: first and last time (s) of each segment, (S,) each; segments merge
    only when their times lie within ``max_span_s`` (:mod:`.windows`).
    Candidate links: each segment with the next ``LINK_BAND`` segments (sorted by ring,
    then time): a few sweeps of the same ring. Sweep ids are not used there: time gaps
    from no-return beams split a sweep into several. Traces are numbered in the order of
    their first segment.
    """
    S = len(segs)
    t0s, t1s = (np.zeros(S), np.zeros(S)) if seg_times is None else seg_times
    lines = _SegmentLines(
        ring=segs.ring,
        sweep=segs.sweep,
        t0=np.asarray(t0s, dtype=np.float64),
        t1=np.asarray(t1s, dtype=np.float64),
        centroid=segs.centroid,
        direction=segs.direction,
        length=segs.length,
        err=direction_error(sigma_m, segs.count, segs.length),
        count=segs.count,
        scatter=segs.scatter,
        end0=segs.end0,
        end1=segs.end1,
    )
    link = _LinkParams(float(tol_m), float(np.radians(parallel_deg)), float(step_m),
                       float(max_span_s), LINK_BAND)  # fmt: skip
    label = _link_segments(lines, link)
    ring, cnt, cen, sc, tdir, lo, hi, t_lo, t_hi = _trace_moments(lines, label)
    # Direction error of a trace: all its points over its length.
    err_t = direction_error(sigma_m, cnt, hi - lo)
    return TraceSet(label, ring, cnt, cen, sc, tdir, lo, hi, err_t, t_lo, t_hi)


@numba.njit(cache=True)
def _link_segments(g, p):  # pragma: no cover - compiled
    """The trace label (S,) of every segment of ``g`` (:class:`_SegmentLines`): linked
    pairs (module docstring) under ``p`` (:class:`_LinkParams`), union-find components
    numbered in the order of their first segment."""
    ring, sweep, centroid, direction, length = g.ring, g.sweep, g.centroid, g.direction, g.length
    t0s, t1s, err = g.t0, g.t1, g.err
    tol_m, parallel_rad, step_m, max_span_s, band = p
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
            # the distance tests first: most pairs fail them, and they need no sine
            s0 = centroid[j, 0] - centroid[i, 0]
            s1 = centroid[j, 1] - centroid[i, 1]
            s2 = centroid[j, 2] - centroid[i, 2]
            along = s0 * direction[i, 0] + s1 * direction[i, 1] + s2 * direction[i, 2]
            if abs(along) > 0.5 * length[i] + 0.5 * length[j] * cosang + tol_m:
                continue
            lateral = np.sqrt(max(s0 * s0 + s1 * s1 + s2 * s2 - along * along, 0.0))
            if lateral > tol_m + step_m:
                continue
            if np.sqrt(max(1.0 - cosang * cosang, 0.0)) > np.sin(
                parallel_rad + 3.0 * (err[i] + err[j])
            ):
                continue
            ri, rj = find_root(parent, i), find_root(parent, j)
            if ri != rj:
                parent[max(ri, rj)] = min(ri, rj)
    return root_labels(parent)[1]  # in the order of each component's first segment


@numba.njit(cache=True)
def _trace_moments(g, label):  # pragma: no cover - compiled
    """Per trace (``label`` (S,) of the segments of ``g``): ring, count, centroid,
    centred scatter, unit direction (weighted mean), extent lo, hi along it and first and
    last time (module docstring)."""
    ring, count, centroid, scatter, direction, length = (
        g.ring, g.count, g.centroid, g.scatter, g.direction, g.length
    )  # fmt: skip
    end0, end1, t0s, t1s = g.end0, g.end1, g.t0, g.t1
    S = ring.shape[0]
    n_lab = 0
    for i in range(S):
        n_lab = max(n_lab, label[i] + 1)
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
    return t_ring, icnt, cen, sc, tdir, lo, hi, t_lo, t_hi
