"""The median of a 1-D array, the same value as ``np.median``, for the many small arrays of
the per-scan loops (an association's residuals, a scan's plane sigmas): ``np.median``
costs ~30 us a call on 25 values, most of it its generic axis and ``mean`` machinery;
one ``np.partition`` costs ~3 us. :func:`block_medians` takes the medians of many
consecutive blocks in one compiled call (a scan's rings: one ``np.median`` call per
ring was a tenth of the extraction of a ringed cloud without times)."""

from __future__ import annotations

import numba
import numpy as np


def median(values: np.ndarray) -> float:
    """``float(np.median(values))``, bit for bit, of the values (N,) (any shape, taken
    flat; converted to float64): the middle value of an odd count, ``(a + b) / 2`` of the
    two middle values of an even one (as numpy's mean, whose sum starts from +0: a median
    of -0.0 is +0.0), NaN when any value is NaN
    (numpy partitions the NaNs to the end, as here) and for N = 0 (numpy's warning
    included)."""
    a = np.asarray(values, dtype=np.float64).reshape(-1)
    n = a.shape[0]
    if n == 0:
        return float(np.median(a))
    h = n // 2
    if n % 2:
        p = np.partition(a, (h, n - 1))
        mid = 0.0 + p[h]
    else:
        p = np.partition(a, (h - 1, h, n - 1))
        mid = (0.0 + p[h - 1] + p[h]) / 2.0
    return float("nan") if np.isnan(p[n - 1]) else float(mid)


def median_at_most(values: np.ndarray, limit: float) -> bool:
    """``median(values) <= limit``, the same verdict, of the values (N,) (any shape, taken
    flat) by counting: more values at most ``limit`` than over it puts both middle values
    at most it (their mean too: rounding is monotonic), fewer puts both over it; only a
    tie (an even count, half on each side) takes the median. A NaN or no value: False (a
    NaN median). For ``|limit|`` under 8e307 (no sum of two middle values overflows).
    One pass instead of a partition of the N values (the pixel normals' tests on a
    64-beam grid: 6 * 10^4 values, ~0.3 ms a partition)."""
    a = np.asarray(values, dtype=np.float64).reshape(-1)
    at_most = int(np.count_nonzero(a <= limit))
    over = int(np.count_nonzero(a > limit))
    if at_most + over < a.shape[0] or a.shape[0] == 0:  # a NaN (or none): a NaN median
        return False
    if at_most != over:
        return at_most > over
    return median(a) <= limit


def block_medians(values: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """(B,) ``np.median(values[bounds[k]:bounds[k + 1]])`` of every block, bit for bit (as
    :func:`median`; NaN for a block holding a NaN or none), of ``values`` (N,) (converted
    to float64) and ``bounds`` (B + 1,) ascending indices."""
    return _block_medians_kernel(
        np.ascontiguousarray(values, dtype=np.float64).reshape(-1),
        np.ascontiguousarray(bounds, dtype=np.int64),
    )


@numba.njit(cache=True)
def _block_medians_kernel(values, bounds):  # pragma: no cover - compiled
    """:func:`block_medians`: per block, the middle order statistic of an odd count, ``(a +
    b) / 2`` of the two middle ones of an even count (``a``: the largest of the lower
    half after the partition), each sum starting from +0 as numpy's mean."""
    out = np.empty(bounds.shape[0] - 1)
    for k in range(out.shape[0]):
        n = bounds[k + 1] - bounds[k]
        block = values[bounds[k] : bounds[k + 1]].copy()
        if n == 0 or np.isnan(block).any():
            out[k] = np.nan
            continue
        h = n // 2
        p = np.partition(block, h)
        if n % 2:
            out[k] = 0.0 + p[h]
        else:
            lo = p[0]
            for i in range(1, h):
                if p[i] > lo:
                    lo = p[i]
            out[k] = (0.0 + lo + p[h]) / 2.0
    return out
