"""Scan lines (rows) of an unorganised spinning-lidar cloud: no ring field, no times; and
of a cloud whose ring field comes without usable times (:func:`ring_scan_rows`).

A cloud stored without a ring field or per-point time (most recorded PCD / PLY / KITTI
files) still carries the structure of the sensor that made it, in one of two forms. Angles
are taken about the sensor origin (``origin``: the rig's sensor origin in the base frame,
where the points are given; the simulator writes points in the base frame, so the origin
matters: a laser's elevation is constant only as seen from the sensor). The sensor's axis
is assumed vertical in the base frame (a tilted mount blurs the elevation modes; the
ring-major form below does not depend on it).

- ring-major order (one laser's whole revolution after the other, as KITTI's Velodyne
  files): the azimuth runs monotonically through one revolution per ring and jumps back by
  about a full turn at every ring change. The rows are the runs between those jumps, in
  file order. A run shorter than ``MIN_RUN_FRACTION`` of the median run (a stray point at
  the wrap) joins its neighbour.
- any other order (column-major firing order of most drivers, or shuffled): the rows are
  the modes of the elevation angle. The lasers of a spinning lidar sit at distinct
  elevations (16 to 128 beams over 20 to 45 deg: spacings of 0.2 to 3 deg); the histogram
  of elevations at ``ELEVATION_BIN_DEG`` is cut at its empty or near-empty bins.

Nothing here is tuned to a dataset: the ring-major test asks for 4 to 512 full-turn jumps
(the beam counts of real spinning lidars) and small azimuth steps within runs (median
below 2 deg). :func:`scan_rows` returns None when neither form holds (too few points, or
fewer than ``MIN_ROWS`` elevation modes: not a multi-beam spinning lidar); the caller
then uses RANSAC.
"""

from __future__ import annotations

import numpy as np

from planodom.extraction.lidar.grid import ring_layout
from planodom.geometry import row_norms
from planodom.median import block_medians, median

#: Runs shorter than this fraction of the median run join their neighbour (ring-major).
MIN_RUN_FRACTION = 0.05
#: Elevation histogram resolution, degrees: a tenth of the finest beam spacing (0.2 deg
#: on 128-beam units) and above the elevation noise of a 1 cm range error at 10 m.
ELEVATION_BIN_DEG = 0.05
#: A histogram bin is a gap below this fraction of the mean occupied bin (near-empty:
#: stray returns, mixed pixels).
GAP_FRACTION = 0.02
#: Fewest rows of a spinning lidar (a 2D scanner has one; 4-beam units exist).
MIN_ROWS = 4
#: Most rows (128-beam units, with margin).
MAX_ROWS = 512
#: A ring field is a spinning lidar's scan lines when each ring lies at one elevation: the
#: median over the rings of a ring's elevation spread (1.4826 MAD) is at most this
#: fraction of the median step between the rings' median elevations. Not from data: a
#: laser's elevation is constant up to the range noise and the laser's offset from the
#: axis (libwave's HDL-32E sweeps, a driver's points from the lasers' calibrated angles:
#: spread / step = 4e-7), while the lines of a non-repetitive scanner (Livox) or a tilted
#: mount sweep through several ring steps (ratio 1 or more); a quarter separates the two.
RING_SPREAD_FRACTION = 0.25


def azimuth(points: np.ndarray) -> np.ndarray:
    """(N,) azimuth (rad) of ``points`` (N, 3) about the z axis."""
    return np.arctan2(points[:, 1], points[:, 0])


def ring_major_rows(points: np.ndarray) -> np.ndarray | None:
    """(N,) int64 row of every point of ``points`` (N, 3), sensor-centred, when the cloud
    is stored ring by ring; None otherwise (module docstring)."""
    if len(points) < 100:
        return None
    phase = np.mod(azimuth(points), 2 * np.pi)
    dphi = np.diff(phase)
    # Within a run the phase grows (or shrinks) slowly; a ring change jumps by ~ -2 pi (or
    # +2 pi): the direction is the median step's.
    med = median(dphi)
    if abs(med) > np.radians(2.0) or med == 0.0:
        return None
    jumps = np.flatnonzero(-np.sign(med) * dphi > np.pi)
    if not MIN_ROWS <= len(jumps) + 1 <= MAX_ROWS:
        return None
    starts = np.r_[0, jumps + 1]
    lengths = np.diff(np.r_[starts, len(points)])
    short = lengths < MIN_RUN_FRACTION * median(lengths)
    starts = starts[~short | (np.arange(len(starts)) == 0)]
    row = np.zeros(len(points), dtype=np.int64)
    row[starts[1:]] = 1
    return np.cumsum(row)


def elevation_rows(points: np.ndarray) -> np.ndarray | None:
    """(N,) int64 row of every point of ``points`` (N, 3), sensor-centred, from the modes
    of its elevation angle, lowest first; None with fewer than ``MIN_ROWS`` modes."""
    if len(points) < 100:
        return None
    r = np.linalg.norm(points, axis=1)
    el = np.degrees(np.arcsin(np.clip(points[:, 2] / np.maximum(r, 1e-9), -1.0, 1.0)))
    b = np.floor((el - el.min()) / ELEVATION_BIN_DEG).astype(np.int64)
    hist = np.bincount(b)
    occupied = hist > GAP_FRACTION * hist[hist > 0].mean()
    starts = np.r_[occupied[0], occupied[1:] & ~occupied[:-1]]
    lab = np.cumsum(starts) - 1
    n_rows = int(lab[-1]) + 1
    if not MIN_ROWS <= n_rows <= MAX_ROWS:
        return None
    # Points in a gap bin join the mode below (lab is constant through a gap).
    return np.maximum(lab[b], 0).astype(np.int64)


def ring_scan_rows(
    points: np.ndarray, ring: np.ndarray, origin: np.ndarray | None = None
) -> np.ndarray | None:
    """Rows (N,) int64 of a cloud ``points`` (N, 3) (m, base frame) with a ``ring`` field
    (N,) but no usable times, seen from ``origin`` (3,) m (default the base origin): the
    rings ordered by their median elevation, lowest first (ring ids need not follow the
    elevation: raw laser ids interleave). None when the rings are not a spinning lidar's
    scan lines: fewer than ``MIN_ROWS`` or more than ``MAX_ROWS`` of them, fewer than 100
    points, or rings that do not lie at one elevation each (``RING_SPREAD_FRACTION``)."""
    if len(points) < 100 or len(ring) != len(points):
        return None
    row, H, order = ring_layout(ring)
    if not MIN_ROWS <= H <= MAX_ROWS:
        return None
    rel = points if origin is None else points - np.asarray(origin, dtype=np.float64)
    r = row_norms(rel)
    el = np.arcsin(np.clip(rel[:, 2] / np.maximum(r, 1e-9), -1.0, 1.0))
    counts = np.bincount(row, minlength=H)
    bounds = np.r_[0, np.cumsum(counts)]
    by_ring = el[order]  # row[order] is np.repeat(np.arange(H), counts): a counting sort
    mid = block_medians(by_ring, bounds)
    spread = 1.4826 * block_medians(np.abs(by_ring - np.repeat(mid, counts)), bounds)
    by_elevation = np.argsort(mid, kind="stable")
    steps = np.diff(mid[by_elevation])
    step = median(steps) if len(steps) else 0.0
    if step <= 0.0 or median(spread) > RING_SPREAD_FRACTION * step:
        return None
    rank = np.empty(H, dtype=np.int64)
    rank[by_elevation] = np.arange(H)
    return rank[row]


def scan_rows(
    points: np.ndarray, origin: np.ndarray | None = None
) -> tuple[np.ndarray, str] | None:
    """Rows (N,) int64 of the unorganised cloud ``points`` (N, 3) (m, base frame) seen
    from ``origin`` (3,) m (default the base origin), and how they were found
    (``"ring-major"`` or ``"elevation"``); None when neither form holds."""
    rel = points if origin is None else points - np.asarray(origin, dtype=np.float64)
    rows = ring_major_rows(rel)
    if rows is not None:
        return rows, "ring-major"
    rows = elevation_rows(rel)
    return None if rows is None else (rows, "elevation")
