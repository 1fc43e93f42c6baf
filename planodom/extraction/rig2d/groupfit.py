"""Robust TLS refit of the 2D-rig groups of segments on their points, all groups at once.

For each group (the segments :func:`.groups.group_segments` put in
one plane):

1. a first plane from the interior points of the segments: a segment's end points are left
   out (when it has ``MIN_TRIMMED`` points or more), since the split tolerance lets the
   last beam before a corner land on the next surface; when every sweep of a scanner
   repeats that point (a still vehicle, or the paper's snapshot simulation), a plane
   from all points is off by mm, and so is the scale below, which then keeps the
   corner points through every refit (the simulated paper loop at sigma = 0: 5.6 mm
   on one epoch per lap);
2. a robust scale: the median over the group's segments of the RMS distance of their
   interior points to that plane (one segment across a corner does not move it; the
   lower middle value for an even count);
3. the inlier points: residual within ``k_sigma`` times that scale, at least 1e-7 m;
4. the fit, two-pass (centred) on the inliers, so that exact data gives exact planes:
   count, centroid, scatter eigenvalues and eigenvectors; then the inliers are chosen
   again with ``k_sigma`` times the RMS of that fit (at least 1e-7 m) and refit, up to
   ``MAX_REFITS`` times, until their count settles: corner points that passed the first
   (segment-level) scale drop out, and noise-free planes become exact;
5. the mean incidence ``|cos|`` of the rays from a viewpoint to the inliers (CPEF,
   :mod:`.confidence`), and the first and last inlier of each run of consecutive points
   (the extreme points of a set of straight pieces are among their ends, so these are
   all the support polygon needs).

Compiled with numba: per group it is a few passes over a few hundred points, with a
median and a 3x3 eigen-decomposition, which in numpy cost more in per-call overhead than
in arithmetic.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np

from planodom.extraction.kernels import add_outer, centred_scatter
from planodom.extraction.planes.builder import PlaneFits
from planodom.extraction.rig2d.segments import Segments

#: Refits of a group after the first (module docstring, step 4).
MAX_REFITS = 3
#: Segments of at least this many points enter steps 1 and 2 without their end points.
MIN_TRIMMED = 5


@dataclass(frozen=True, eq=False)
class GroupFits:
    """Final fits of G groups.

    Attributes:
        count: (G,) int64 inliers. centroid: (G, 3) metres.
        evals: (G, 3) scatter eigenvalues, ascending, m^2.
        evecs: (G, 3, 3) eigenvectors (columns, ascending: normal first).
        incidence: (G,) mean |cos| of the rays from the viewpoint (1 without one).
        inliers: (K,) int64 positions in ``segs.points`` of all inliers, group by group.
        bounds: (G + 1,) group g's inliers are ``inliers[bounds[g]:bounds[g + 1]]``.
        is_end: (K,) bool, the inlier starts or ends a run of consecutive positions.
    """

    count: np.ndarray
    centroid: np.ndarray
    evals: np.ndarray
    evecs: np.ndarray
    incidence: np.ndarray
    inliers: np.ndarray
    bounds: np.ndarray
    is_end: np.ndarray


class _SegmentPoints(NamedTuple):
    """The segments as the compiled refit reads them: points (M, 3) m, starts, ends (S,)
    int64 (segment s holds ``points[starts[s]:ends[s]]``)."""

    points: np.ndarray
    starts: np.ndarray
    ends: np.ndarray


def fit_groups(
    segs: Segments,
    groups: list[np.ndarray],
    k_sigma: float,
    viewpoint: np.ndarray | None,
) -> GroupFits:
    """Refit every group (module docstring).

    Args:
        segs: the epoch's segments. groups: per group, (S_g,) segment indices.
        k_sigma: inlier threshold in robust scales (``inlier_sigma_factor``).
        viewpoint: (3,) metres, origin of the rays for the incidence; None: incidence 1.
    """
    sizes = np.array([len(g) for g in groups], dtype=np.int64)
    gseg = np.concatenate(groups).astype(np.int64) if len(groups) else np.zeros(0, np.int64)
    gb = np.zeros(len(groups) + 1, dtype=np.int64)
    np.cumsum(sizes, out=gb[1:])
    view = np.zeros(3) if viewpoint is None else np.asarray(viewpoint, dtype=np.float64)
    seg = _SegmentPoints(segs.points, segs.starts, segs.ends)
    out = _fit_groups_kernel(seg, gseg, gb, float(k_sigma), view, viewpoint is not None)
    return GroupFits(*out)


def plane_fits(
    segs: Segments,
    groups: list[np.ndarray],
    k_sigma: float,
    viewpoint: np.ndarray | None,
) -> PlaneFits:
    """:func:`fit_groups` as the plane builder's input, in one compiled call.

    The same bits as :func:`fit_groups` followed by: the eigenvalues descending and the
    eigenvector columns e1, e2, n (reversed views of the refit's ascending arrays), the
    offsets ``-n . centroid`` (summed in :func:`numpy.einsum`'s order), the inliers as
    scan indices (``segs.order``), and the incidence only with a viewpoint (else None).

    Args:
        segs: the epoch's segments. groups: per group, (S_g,) segment indices.
        k_sigma: inlier threshold in robust scales (``inlier_sigma_factor``).
        viewpoint: (3,) metres, origin of the rays for the incidence; None: incidence
            not computed.
    """
    sizes = np.fromiter(map(len, groups), np.int64, len(groups))
    gseg = np.concatenate(groups).astype(np.int64, copy=False) if groups else sizes
    view = np.zeros(3) if viewpoint is None else np.asarray(viewpoint, dtype=np.float64)
    cnt, cen, off, vals, vecs, inc, inl, bnd, is_end = _plane_fits_kernel(
        segs.points, segs.starts, segs.ends, segs.order, gseg, sizes, float(k_sigma), view,
        viewpoint is not None,
    )  # fmt: skip
    return PlaneFits(
        count=cnt, centroid=cen, offset=off, evals=vals[:, ::-1], evecs=vecs[:, :, ::-1],
        inliers=inl, bounds=bnd, outline=is_end, incidence=None if viewpoint is None else inc,
    )  # fmt: skip


@numba.njit(cache=True)
def _interior(seg, s):  # pragma: no cover - compiled
    """The positions ``[lo, hi)`` of segment ``s``'s interior points: without its two end
    points when it has ``MIN_TRIMMED`` or more (an end point may lie on the next surface,
    step 1), else all."""
    lo, hi = seg.starts[s], seg.ends[s]
    if hi - lo >= MIN_TRIMMED:
        return lo + 1, hi - 1
    return lo, hi


@numba.njit(cache=True)
def _first_plane(seg, members):  # pragma: no cover - compiled
    """Step 1: unit normal (3,) and offset (m) of the interior points of the segments
    ``members`` (K,) (two passes, centred; scalar loops, no per-point arrays)."""
    pts = seg.points  # read once: through the named tuple in the loops it cost ~10x
    cnt = 0.0
    c0 = c1 = c2 = 0.0
    for s in members:
        lo, hi = _interior(seg, s)
        for i in range(lo, hi):
            cnt += 1.0
            c0 += pts[i, 0]
            c1 += pts[i, 1]
            c2 += pts[i, 2]
    cnt = max(cnt, 1e-300)
    c = np.array([c0 / cnt, c1 / cnt, c2 / cnt])
    sc = np.zeros((3, 3))
    for s in members:
        lo, hi = _interior(seg, s)
        for i in range(lo, hi):
            add_outer(sc, pts[i, 0] - c[0], pts[i, 1] - c[1], pts[i, 2] - c[2])
    sc[1, 0], sc[2, 0], sc[2, 1] = sc[0, 1], sc[0, 2], sc[1, 2]
    _, vecs = np.linalg.eigh(sc)
    n = vecs[:, 0].copy()
    return n, -(n[0] * c[0] + n[1] * c[1] + n[2] * c[2])


@numba.njit(cache=True)
def _robust_scale(seg, members, n, d):  # pragma: no cover - compiled
    """Step 2: the median (the lower middle value for an even count) of the segments'
    RMS distances (m) of their interior points to the plane (n, d)."""
    pts = seg.points
    rms = np.empty(members.shape[0])
    for k in range(members.shape[0]):
        lo, hi = _interior(seg, members[k])
        q = 0.0
        for i in range(lo, hi):
            r = pts[i, 0] * n[0] + pts[i, 1] * n[1] + pts[i, 2] * n[2] + d
            q += r * r
        rms[k] = np.sqrt(q / max(hi - lo, 1))
    rms.sort()
    return rms[(members.shape[0] - 1) // 2]


@numba.njit(cache=True)
def _select(seg, members, n, d, thr, inl, buf, start, centroid):  # pragma: no cover
    """Step 3: write the points of the segments ``members`` within ``thr`` (m) of the
    plane (n, d) to ``inl`` (their positions) and ``buf`` (the points) from ``start`` on;
    returns the end, and fills ``centroid`` (3,) with their mean (when any): the sums of
    :func:`.kernels.range_moments`' first pass, in its order (so the same bits), taken here
    instead of in three more passes over them."""
    pts, starts, ends = seg.points, seg.starts, seg.ends
    K = start
    a0 = a1 = a2 = 0.0
    for s in members:
        for i in range(starts[s], ends[s]):
            p0, p1, p2 = pts[i, 0], pts[i, 1], pts[i, 2]
            if abs(p0 * n[0] + p1 * n[1] + p2 * n[2] + d) <= thr:
                inl[K] = i
                buf[K, 0], buf[K, 1], buf[K, 2] = p0, p1, p2
                a0 += p0
                a1 += p1
                a2 += p2
                K += 1
    if K > start:
        centroid[0], centroid[1], centroid[2] = a0 / (K - start), a1 / (K - start), a2 / (K - start)
    return K


@numba.njit(cache=True)
def _refit(seg, members, k_sigma, inl, buf, start):  # pragma: no cover - compiled
    """Steps 1 to 4 for one group: the end K of its inliers in ``inl`` (from ``start``),
    whether it was fit (3 inliers or more), its centroid (3,), eigenvalues (3,) and
    eigenvectors (3, 3) of the scatter (ascending)."""
    n, d = _first_plane(seg, members)
    thr = max(k_sigma * _robust_scale(seg, members, n, d), 1e-7)
    m = 0
    c2 = np.zeros(3)
    sc2 = np.empty((3, 3))
    vals = np.zeros(3)
    vecs2 = np.eye(3)
    mean = np.zeros(3)
    for it in range(MAX_REFITS + 1):
        K = _select(seg, members, n, d, thr, inl, buf, start, mean)
        m_prev = m
        m = K - start
        if m < 3:
            return start + m, False, c2, vals, vecs2
        c2[0], c2[1], c2[2] = mean[0], mean[1], mean[2]
        centred_scatter(buf, start, K, c2, sc2)  # range_moments, its first pass done
        vals, vecs2 = np.linalg.eigh(sc2)
        if it > 0 and m == m_prev:
            break
        n = vecs2[:, 0].copy()
        d = -(n[0] * c2[0] + n[1] * c2[1] + n[2] * c2[2])
        thr = max(k_sigma * np.sqrt(max(vals[0], 0.0) / m), 1e-7)
    return start + m, True, c2, vals, vecs2


@numba.njit(cache=True)
def _fit_groups_kernel(seg, gseg, gb, k_sigma, view, use_view):  # pragma: no cover
    """All groups (``gseg[gb[g]:gb[g + 1]]`` the segments of group g): the fields of
    :class:`GroupFits`, in order."""
    G = gb.shape[0] - 1
    pts = seg.points
    total = 0
    for k in range(gseg.shape[0]):
        total += seg.ends[gseg[k]] - seg.starts[gseg[k]]
    inl = np.empty(total, dtype=np.int64)
    buf = np.empty((total, 3))  # the inlier points, contiguous for centred_scatter
    is_end = np.zeros(total, dtype=np.bool_)
    bounds = np.zeros(G + 1, dtype=np.int64)
    cnt_out = np.zeros(G, dtype=np.int64)
    cen_out = np.zeros((G, 3))
    vals_out = np.zeros((G, 3))
    vecs_out = np.zeros((G, 3, 3))
    inc_out = np.ones(G)
    K = 0
    for g in range(G):
        start = K
        bounds[g] = start
        K, fitted, c2, vals, vecs2 = _refit(seg, gseg[gb[g] : gb[g + 1]], k_sigma, inl, buf, start)
        m = K - start
        cnt_out[g] = m
        bounds[g + 1] = K
        if not fitted:
            continue
        cen_out[g] = c2
        vals_out[g] = vals
        vecs_out[g] = vecs2
        # 5. Incidence and run ends.
        if use_view:
            acc = 0.0
            n0, n1, n2 = vecs2[0, 0], vecs2[1, 0], vecs2[2, 0]
            for j in range(start, K):
                i = inl[j]
                r0 = pts[i, 0] - view[0]
                r1 = pts[i, 1] - view[1]
                r2 = pts[i, 2] - view[2]
                r = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
                acc += abs(r0 * n0 + r1 * n1 + r2 * n2) / max(r, 1e-300)
            inc_out[g] = acc / m
        for j in range(start, K):
            first = j == start or inl[j] != inl[j - 1] + 1
            last = j == K - 1 or inl[j + 1] != inl[j] + 1
            is_end[j] = first or last
    return (
        cnt_out, cen_out, vals_out, vecs_out, inc_out, inl[:K].copy(), bounds,
        is_end[:K].copy(),
    )  # fmt: skip


@numba.njit(cache=True)
def _plane_fits_kernel(
    points, starts, ends, order, gseg, sizes, k_sigma, view, use_view
):  # pragma: no cover - compiled
    """:func:`_fit_groups_kernel` on the groups of ``sizes`` (G,) segments each, listed
    in ``gseg``: count, centroid, offset (G,) of the normal (the first eigenvector)
    through the centroid, eigenvalues and eigenvectors (ascending), incidence, inliers
    as ``order`` indices, bounds and run ends."""
    gb = np.zeros(sizes.shape[0] + 1, dtype=np.int64)
    for g in range(sizes.shape[0]):
        gb[g + 1] = gb[g] + sizes[g]
    seg = _SegmentPoints(points, starts, ends)
    cnt, cen, vals, vecs, inc, inl, bnd, is_end = _fit_groups_kernel(
        seg, gseg, gb, k_sigma, view, use_view
    )
    off = np.empty(cnt.shape[0])
    for g in range(cnt.shape[0]):
        acc = 0.0  # einsum's order: from zero, one term after the other
        for i in range(3):
            acc += vecs[g, i, 0] * cen[g, i]
        off[g] = -acc
    idx = np.empty(inl.shape[0], dtype=order.dtype)
    for j in range(inl.shape[0]):
        idx[j] = order[inl[j]]
    return cnt, cen, off, vals, vecs, inc, idx, bnd, is_end
