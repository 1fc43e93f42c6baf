"""The range noise of a 2D rig's scan lines (``extraction.noise_estimate: range``).

:func:`.scanlines.estimate_line_noise_2d` measures the noise across the scan lines: the
second difference ``p[c-1] - 2 p[c] + p[c+1]`` across the chord ``p[c+2] - p[c-2]``.
Range noise ``e`` moves a point along its ray ``r``, so across a line it shows only as
``e sin(a)``, ``a`` the angle between the ray and the line (the sensor lies in its own
scan plane, so ray and line span it): an oblique wall's lines look quieter than the
scanner is. Dividing each second difference by ``sin(a)`` gives ``e[c-1] - 2 e[c] +
e[c+1]`` whatever the incidence, and the same robust median as the across-line estimate
turns it into the range noise sigma. A line seen along its ray (``sin(a)`` zero) says
nothing and is skipped; the median keeps the few near it from weighing.
"""

from __future__ import annotations

import numba
import numpy as np

from planodom.extraction.kernels import median_nonnegative


@numba.njit(cache=True)
def estimate_range_noise_2d(x, y, pts, ring_sorted, origins, run_start):  # pragma: no cover
    """The range noise sigma (m) of points sorted by ring (module docstring): ``x``, ``y``
    (M,) their coordinates in their ring's plane (:func:`.scanlines.ring_plane_coordinates`),
    ``pts`` (M, 3) the same points (m, base frame), ``ring_sorted`` (M,) int64 their
    rings, ``origins`` (R, 3) the sensor origin of each ring id (m; one row: one for all)
    and ``run_start`` (M,) bool where runs start. 0.0 with fewer than 15 points or
    fewer than 10 usable second differences (as the across-line estimate)."""
    m = x.shape[0]
    if m < 15:
        return 0.0
    ratio = np.empty(m)
    k = 0
    run = np.cumsum(run_start)
    for c in range(2, m - 2):  # points c with c-2 .. c+2 in one run
        if run[c + 2] != run[c - 2]:
            continue
        dx, dy = x[c + 2] - x[c - 2], y[c + 2] - y[c - 2]
        norm = np.sqrt(dx * dx + dy * dy)
        if not norm > 0:
            continue
        sx = x[c - 1] - 2.0 * x[c] + x[c + 1]
        sy = y[c - 1] - 2.0 * y[c] + y[c + 1]
        o = origins[ring_sorted[c] if origins.shape[0] > 1 else 0]
        r0, r1, r2 = pts[c, 0] - o[0], pts[c, 1] - o[1], pts[c, 2] - o[2]
        d0 = pts[c + 2, 0] - pts[c - 2, 0]
        d1 = pts[c + 2, 1] - pts[c - 2, 1]
        d2 = pts[c + 2, 2] - pts[c - 2, 2]
        c0, c1, c2 = r1 * d2 - r2 * d1, r2 * d0 - r0 * d2, r0 * d1 - r1 * d0
        rd = np.sqrt((r0 * r0 + r1 * r1 + r2 * r2) * (d0 * d0 + d1 * d1 + d2 * d2))
        sin_a = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2) / rd if rd > 0 else 0.0
        if not sin_a > 0:
            continue
        ratio[k] = abs(sx * dy - sy * dx) / norm / sin_a
        k += 1
    if k < 10:
        return 0.0
    return median_nonnegative(ratio, k) / (0.6745 * np.sqrt(6.0))
