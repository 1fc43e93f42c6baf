"""Whether a trace lies on a plane: the 2D-rig grouping's membership test (compiled).

Shared by the grouping's growth (:mod:`.grouping`) and the gap bridge (:mod:`.bridge`).
"""

from __future__ import annotations

import numba


@numba.njit(cache=True)
def trace_fits(centroid, scatter, direction, lo, hi, count, t, n, d, tol):  # pragma: no cover
    """Trace ``t``'s RMS distance to the plane (n, d) and its end points (the ends of its
    extent, at its centroid's offset) are within ``tol`` (``count``: (T,) float64; the
    trace arrays one by one: read through the named tuple they cost ~10x the maths)."""
    off = centroid[t, 0] * n[0] + centroid[t, 1] * n[1] + centroid[t, 2] * n[2] + d
    slope = direction[t, 0] * n[0] + direction[t, 1] * n[1] + direction[t, 2] * n[2]
    ends = max(abs(off + slope * lo[t]), abs(off + slope * hi[t]))
    if not ends <= tol:  # most (seed, trace) pairs end here: the scatter's form is skipped
        return False
    q = 0.0
    for u in range(3):
        for v in range(3):
            q += n[u] * scatter[t, u, v] * n[v]
    return q / count[t] + off * off <= tol * tol
