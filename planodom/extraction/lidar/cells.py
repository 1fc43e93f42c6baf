"""Angular cells of a scan's points as seen from the viewpoint, and the points of each cell:
the RANSAC fallback's clustering grid (:mod:`planodom.extraction.lidar.candidates`, step 3).

A cell is ``cell_deg`` in azimuth (wrapping at ``n_az``) and in elevation. The points of
a cell are found through one counting sort by the cell's key ``az * n_el + el``
(:func:`cell_members`), so that the points of the cells a cluster covers are visited
without a pass over every point of their azimuth columns (:func:`.clusters.cell_buckets`).
"""

from __future__ import annotations

import numba
import numpy as np

from planodom.extraction.lidar.grid import plane_members


def angular_cells(points: np.ndarray, viewpoint: np.ndarray, cell_deg: float) -> np.ndarray:
    """(N, 2) int64 (azimuth, elevation) cells of ``cell_deg`` of the points (N, 3) m seen
    from ``viewpoint`` (3,) m (the azimuth not wrapped)."""
    rel = points - viewpoint
    az = np.arctan2(rel[:, 1], rel[:, 0])
    el = np.arctan2(rel[:, 2], np.hypot(rel[:, 0], rel[:, 1]))
    cell = np.radians(cell_deg)
    return np.floor(np.column_stack([(az + np.pi) / cell, (el + np.pi / 2) / cell])).astype(
        np.int64
    )


def cell_index(
    points: np.ndarray, viewpoint: np.ndarray, cell_deg: float, n_az: int
) -> tuple[np.ndarray, np.ndarray]:
    """``(az, el)`` (N,) int64 each, contiguous: :func:`angular_cells` of the points
    (N, 3) m seen from ``viewpoint`` (3,) m, the azimuth wrapped to ``[0, n_az)``.

    The same numbers as ``angular_cells(...)[:, 0] % n_az`` and ``[:, 1]``: numpy's
    ``arctan2`` and ``hypot`` on the same operands, then the same IEEE operations (add,
    divide, floor, floor modulo) in one compiled pass (numba, no fast-math) instead of six
    numpy passes with their temporaries (tests/extraction/test_cells.py)."""
    rel = points - viewpoint
    az = np.arctan2(rel[:, 1], rel[:, 0])
    el = np.arctan2(rel[:, 2], np.hypot(rel[:, 0], rel[:, 1]))
    return _cells_kernel(az, el, float(np.radians(cell_deg)), int(n_az))


@numba.njit(cache=True)
def _cells_kernel(az, el, cell, n_az):  # pragma: no cover - compiled
    """The cells of the angles ``az``, ``el`` (N,) rad: ``floor((az + pi) / cell) %
    n_az`` and ``floor((el + pi / 2) / cell)``."""
    n = az.shape[0]
    a = np.empty(n, dtype=np.int64)
    e = np.empty(n, dtype=np.int64)
    half = np.pi / 2
    for i in range(n):
        a[i] = np.int64(np.floor((az[i] + np.pi) / cell)) % n_az
        e[i] = np.int64(np.floor((el[i] + half) / cell))
    return a, e


def cell_members(
    az: np.ndarray, el: np.ndarray, n_az: int, n_el: int
) -> tuple[np.ndarray, np.ndarray]:
    """The points of every cell, ascending: ``(idx (N,), bounds (n_az n_el + 1,))``, cell
    ``(a, e)`` holding ``idx[bounds[a n_el + e]:bounds[a n_el + e + 1]]``; ``az`` (N,) in
    ``[0, n_az)``, ``el`` (N,) in ``[0, n_el)``, int64."""
    return plane_members(az * n_el + el, n_az * n_el)
