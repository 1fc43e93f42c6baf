"""Multi-return clouds (dual / triple return lidars) reduced to one return per beam firing.

A lidar in dual-return mode reports up to two points per beam and firing (Ouster, Hesai,
Velodyne, Robosense: strongest and last, or first and last), with the firing's ring and
time, and often a field naming the return (nebula's ``return_type``). Kept as they are,
every surface the beam hits squarely is counted twice (twice the weight of a plane seen
in single-return mode, with half the noise it really has), and the two returns of a
ring interleave, so the ring is no longer one run of increasing azimuth (the recovered
rows of :mod:`planodom.extraction.lidar.rows`).

Kept here: for every beam firing, the farthest of its returns, i.e. the **last return**
(the hard surface behind glass, foliage or dust; on a plain wall both returns coincide).
A firing is a ``(ring, time)`` pair: one beam fires once at one time, so two points that
share both are returns of one pulse, provided they lie on one ray (some drivers stamp two
firings of a beam with one time; then nothing is dropped). This is done when

- the cloud has a return field (:data:`RETURN_FIELDS`) with more than one value, or
- without one, some firings have 2 or 3 points and none more (a dual or triple return
  cloud; a driver whose times are per packet rather than per firing gives many points per
  ``(ring, time)`` and is left alone).

With a return field but no ring, no per-point time, times coarser than a firing, or times
of each return's own (nebula's Hesai clouds: the returns of one pulse differ in time),
returns cannot be paired, and every point is kept (see :func:`last_returns` why not one
return value).
"""

from __future__ import annotations

import numpy as np

#: Names of a per-point return field (which return of its pulse a point is), first wins.
RETURN_FIELDS = ("return_type", "return", "returns", "echo")
#: Most returns a lidar reports per pulse (triple-return modes exist; none report more).
MAX_RETURNS = 3
#: Largest angle (rad) between the directions of two points taken as returns of one pulse:
#: they lie on one ray from the sensor (float32 coordinates: ~1e-6 rad apart), while the
#: next firing of a beam is at least ~0.1 deg away on the spinning lidars we know of
#: (AT128 0.1, VLP-16 0.2, Ouster 2048 0.18, QT64 0.6 deg). Not from data.
RAY_TOLERANCE_RAD = np.deg2rad(0.02)


def last_returns(
    points: np.ndarray,
    ring: np.ndarray | None,
    t: np.ndarray | None,
    returns: np.ndarray | None,
) -> np.ndarray | None:
    """Indices (M,) of the points to keep, in their order, or None to keep every point.

    Args:
        points: (N, 3) float64 metres in the sensor (or base) frame; ranges from the origin.
        ring: (N,) ring ids or None.
        t: (N,) per-point times (any unit; only equality is used), or None when the
            cloud has none.
        returns: (N,) the return field or None.
    """
    n = len(points)
    labelled = returns is not None and len(np.unique(returns)) > 1
    if n == 0 or (returns is not None and not labelled):
        return None
    dist = np.einsum("ij,ij->i", points, points)
    if ring is not None and t is not None and np.ptp(t) > 0:  # constant: no firing times
        firing, counts = _firings(np.asarray(ring, np.float64), np.asarray(t, np.float64))
        if counts.max() == 1:
            return None  # one point per firing: single return already
        order = np.lexsort((dist, firing))  # by firing, then range: each firing's last
        ends = np.flatnonzero(np.diff(firing[order], append=firing[order][-1] + 1))
        if counts.max() <= MAX_RETURNS and _one_ray_each(points, firing, order[ends]):
            return np.sort(order[ends])
    # Returns that cannot be paired by firing are all kept (double weight on surfaces hit
    # twice), not reduced to one return value: the values' meaning is the driver's (nebula
    # labels returns that coincide as a class of their own, "identical"), and keeping the
    # value of largest median range kept 112 of 14 673 points of a dual-return VLP-16
    # scan and 354 of 108 663 of a Pandar40P one (nebula's test scans).
    return None


def _one_ray_each(points: np.ndarray, firing: np.ndarray, last: np.ndarray) -> bool:
    """Whether every point lies on the ray of its firing's last return (``last``: (F,)
    indices of each firing's farthest point, in firing order), i.e. the ``(ring, time)``
    groups are pulses. nebula's VLP-16 clouds give two firings 1.2 deg apart one time
    stamp: those are not returns of one pulse, and the cloud is left whole. Points in a
    base frame away from the sensor fail this too, and are left whole (the safe side)."""
    norm = np.linalg.norm(points, axis=1)
    unit = points / np.where(norm > 0, norm, 1.0)[:, None]
    cos = np.einsum("ij,ij->i", unit, unit[last][firing])
    return bool(np.all(cos >= np.cos(RAY_TOLERANCE_RAD)))


def _firings(ring: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each point's firing, the rank (n,) of its distinct ``(ring, t)`` pair in their
    lexicographic order, and the points (F,) of each firing: ``np.unique`` of the pairs
    with ``axis=0`` (its inverse and counts, the same numbers), which sorts the rows as
    structured values: 39 s of a 10M-point cloud's 62 s of reading, where two sort keys
    take a few seconds."""
    order = np.lexsort((t, ring))
    r, s = ring[order], t[order]
    new = np.empty(len(order), dtype=bool)
    new[:1] = True
    new[1:] = (r[1:] != r[:-1]) | (s[1:] != s[:-1])  # as np.unique: NaN is never equal
    firing = np.empty(len(order), dtype=np.intp)
    firing[order] = np.cumsum(new) - 1
    counts = np.diff(np.append(np.flatnonzero(new), len(order)))
    return firing, counts
