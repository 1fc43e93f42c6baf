"""What an extraction derives from a scan's own fields, each in one compiled pass.

Every epoch's first extraction checks the scan's points and times
(:func:`planodom.extraction.pipeline._check_points_times`), counts its rings
(:func:`planodom.extraction.pipeline.count_rings`) and, on the 2D-rig path, orders its
points by ring (:func:`planodom.extraction.rig2d.segments.ring_order`); the memo
(:mod:`.memo`) spares the epoch's later extractions. In numpy these were 4-12 calls over
the scan each (about 100 us a scan for the ring order on world 162's 2 900 points,
SPEED2D12). Here each is one pass over the scan, and each answer is the numpy form's to
the bit: only comparisons, integer counts and copies, no floating-point arithmetic but
the median beam interval's, which is the same compiled kernel
(:func:`.rig2d.scanlines._timing_kernel`) on the same arrays. The numpy forms stay as
the callers' fallback (other dtypes, wide ring ids) and as the tests' reference.
"""

from __future__ import annotations

import numba
import numpy as np

from planodom.extraction.rig2d.scanlines import _timing_kernel

#: Ring ids spanning fewer values than this are sorted by counting (numpy's form sorts
#: them as uint16 keys: the same bound).
RING_SPAN = 1 << 16


def _plain_ints(a: object) -> bool:
    """Whether ``a`` is a 1-D int32 / int64 array (the compiled passes' ring ids)."""
    return isinstance(a, np.ndarray) and a.ndim == 1 and a.dtype in (np.int32, np.int64)


def compiled_ring_order(
    ring: np.ndarray, t: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, tuple[float, bool]] | None:
    """:func:`planodom.extraction.rig2d.segments.numpy_ring_order` of ``ring`` (N,) and
    ``t`` (N,) s or None in one compiled call (not read-only yet), or None when it does
    not apply: ring ids not int32 / int64, times not float64 of the same length, or ids
    spanning :data:`RING_SPAN` values or more. The stable order by ring is the counting
    sort's (a stable sort's permutation is unique), the rings and times gathered, the
    timing the same kernel's."""
    if not _plain_ints(ring):
        return None
    has_t = t is not None
    if has_t and not (
        isinstance(t, np.ndarray) and t.dtype == np.float64 and t.shape == ring.shape
    ):
        return None
    tt_in = t if has_t else np.zeros(0)
    done, order, rg, tt, med, forward = _ring_order_kernel(ring, tt_in, has_t, RING_SPAN)
    if not done:
        return None
    return order, rg, (tt if has_t else None), (float(med), bool(forward))


@numba.njit(cache=True)
def _ring_order_kernel(ring, t, has_t, span):  # pragma: no cover - compiled
    """:func:`compiled_ring_order`: ``(done, order, rings, times, median, forward)``;
    ``done`` False when the ids span ``span`` values or more (nothing else computed)."""
    m = ring.shape[0]
    unsorted = False
    for i in range(1, m):
        if ring[i] < ring[i - 1]:
            unsorted = True
            break
    order = np.empty(m, dtype=np.int64)
    if unsorted:
        lo, hi = ring[0], ring[0]
        for i in range(m):
            lo = min(lo, ring[i])
            hi = max(hi, ring[i])
        width = np.int64(hi) - np.int64(lo)
        if width >= span:
            return False, order, np.empty(0, np.int64), np.empty(0), 0.0, False
        start = np.zeros(width + 2, dtype=np.int64)
        for i in range(m):
            start[np.int64(ring[i]) - lo + 1] += 1
        for k in range(1, width + 2):
            start[k] += start[k - 1]
        for i in range(m):  # in index order within a key: stable
            k = np.int64(ring[i]) - lo
            order[start[k]] = i
            start[k] += 1
    else:
        for i in range(m):
            order[i] = i
    rg = np.empty(m, dtype=np.int64)
    tt = np.zeros(m)  # beam_timing's zeros without times
    for i in range(m):
        rg[i] = ring[order[i]]
        if has_t:
            tt[i] = t[order[i]]
    med, forward = _timing_kernel(rg, tt, has_t)
    return True, order, rg, tt, med, forward


def points_times_finite(pts: np.ndarray, t: np.ndarray | None, limit: float) -> bool | None:
    """Whether a scan's points (N, 3) are finite and within ``limit`` m in every coordinate
    and its times (N,) s (or None) finite, in one compiled pass; None when the arrays are
    not float64 (N, 3) C-contiguous and (N,) (the caller's numpy checks apply). The same
    decision as ``isfinite(pts).all()``, ``max(pts.max(), -pts.min()) <= limit`` and
    ``isfinite(t).all()`` (comparisons only)."""
    if not (
        isinstance(pts, np.ndarray) and pts.dtype == np.float64 and pts.ndim == 2
        and pts.shape[1] == 3 and pts.flags.c_contiguous
    ):  # fmt: skip
        return None
    has_t = t is not None
    if has_t and not (isinstance(t, np.ndarray) and t.dtype == np.float64 and t.ndim == 1):
        return None
    return bool(_finite_kernel(pts, t if has_t else np.zeros(0), has_t, float(limit)))


@numba.njit(cache=True)
def _finite_kernel(pts, t, has_t, limit):  # pragma: no cover - compiled
    """:func:`points_times_finite`: NaN fails every comparison, so ``-limit <= x <= limit``
    holds only for finite coordinates within the limit; ``t - t == 0`` only for finite
    times."""
    for i in range(pts.shape[0]):
        for j in range(3):
            x = pts[i, j]
            if not (x <= limit and x >= -limit):
                return False
    if has_t:
        for i in range(t.shape[0]):
            if not (t[i] - t[i] == 0.0):
                return False
    return True


def compiled_count_rings(ring: np.ndarray) -> int | None:
    """The number of distinct ids in ``ring`` (N,) int32 / int64 with ids in [0,
    :data:`RING_SPAN`), as ``count_nonzero(bincount(ring))``; None otherwise (other
    dtypes, negative or wide ids: the caller's numpy form)."""
    if not _plain_ints(ring):
        return None
    n = int(_count_kernel(ring, RING_SPAN))
    return None if n < 0 else n


@numba.njit(cache=True)
def _count_kernel(ring, span):  # pragma: no cover - compiled
    """:func:`compiled_count_rings`; -1 when an id lies outside [0, span)."""
    seen = np.zeros(span, dtype=np.bool_)
    n = 0
    for i in range(ring.shape[0]):
        r = np.int64(ring[i])
        if r < 0 or r >= span:
            return -1
        if not seen[r]:
            seen[r] = True
            n += 1
    return n
