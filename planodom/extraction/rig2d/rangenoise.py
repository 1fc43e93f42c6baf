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

from planodom.extraction.rig2d.scanlines import noise_sigma_2d


@numba.njit(cache=True)
def estimate_range_noise_2d(x, y, pts, ring_sorted, origins, run_start):  # pragma: no cover
    """The range noise sigma (m) of points sorted by ring (module docstring): ``x``, ``y``
    (M,) their coordinates in their ring's plane (:func:`.scanlines.ring_plane_coordinates`),
    ``pts`` (M, 3) the same points (m, base frame), ``ring_sorted`` (M,) int64 their
    rings, ``origins`` (R, 3) the sensor origin of each ring id (m; one row: one for all)
    and ``run_start`` (M,) bool where runs start. 0.0 with fewer than 15 points or
    fewer than 10 usable second differences (as the across-line estimate)."""
    return noise_sigma_2d(x, y, run_start, pts, ring_sorted, origins, True)
