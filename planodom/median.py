"""The median of a 1-D array, the same value as ``np.median``, for the many small arrays of
the per-scan loops (an association's residuals, a scan's plane sigmas): ``np.median``
costs ~30 us a call on 25 values, most of it its generic axis and ``mean`` machinery;
one ``np.partition`` costs ~3 us."""

from __future__ import annotations

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
