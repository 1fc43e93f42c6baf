"""Decimation of a dense lidar's organised image (``extraction.grid_max_columns``,
``grid_max_rows``).

A scan whose grid (:func:`.grid.grid_indices`: rows from the ring field or the recovered
rows, columns from the times) has more columns or rows than the limits keeps every k-th
column (``k = ceil(W / grid_max_columns)``, columns counted from the first firing) and
every k-th row; the extraction then runs on that subset as on a sparser lidar's scan, and
the inlier sets are mapped back to the scan's indices. What is kept depends on the scan's
ring and times alone, so it is memoised (:mod:`planodom.extraction.memo`) and the subset
scan is the same object in every extraction of the epoch (its own memoised grid, ring
order, rows).
"""

from __future__ import annotations

import math

import numpy as np

from planodom.extraction.lidar.grid import grid_indices
from planodom.extraction.memo import identity_memo, read_only
from planodom.scan import Scan


def kept_points(
    ring: np.ndarray, t: np.ndarray | None, max_columns: int | None, max_rows: int | None
) -> np.ndarray | None:
    """(M,) int64 ascending indices of the points kept from a scan with ``ring`` (N,) and
    times ``t`` (N,) s under the limits (module docstring); None when every point is kept
    (no limit exceeded, or no grid). Memoised, read-only."""
    if max_columns is None and max_rows is None:
        return None
    return _kept(ring, t, max_columns, max_rows)


@identity_memo
def _kept(
    ring: np.ndarray, t: np.ndarray | None, max_columns: int | None, max_rows: int | None
) -> np.ndarray | None:
    row, col, H, W = grid_indices(ring, t)
    if col is None:
        return None
    k_col = 1 if max_columns is None else math.ceil(W / max_columns)
    k_row = 1 if max_rows is None else math.ceil(H / max_rows)
    if k_col == 1 and k_row == 1:
        return None
    keep = (col % k_col == 0) & (row % k_row == 0)
    return read_only(np.flatnonzero(keep))


def subset_scan(scan: Scan, ring: np.ndarray, keep: np.ndarray) -> tuple[Scan, np.ndarray]:
    """The points ``keep`` (M,) of ``scan`` as a scan (its ring replaced by ``ring``
    (N,)) and that ring's subset (M,); the same objects for the same arrays (memoised)."""
    return _subset(scan.points, ring, scan.t, scan.label, keep)


@identity_memo
def _subset(
    points: np.ndarray,
    ring: np.ndarray,
    t: np.ndarray | None,
    label: np.ndarray | None,
    keep: np.ndarray,
) -> tuple[Scan, np.ndarray]:
    sub_ring = read_only(ring[keep])
    sub = Scan(
        points[keep],
        sub_ring,
        None if t is None else t[keep],
        None if label is None else label[keep],
    )
    return sub, sub_ring
