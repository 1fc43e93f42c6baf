"""A lidar topic whose ring ids do not follow its beams' elevations: renumbered, noted.

The range image of a ringed scan takes rings in id order as neighbouring rows
(:mod:`planodom.extraction.lidar.grid`), which a driver's ``ring`` field follows (lowest
beam first, or highest: Velodyne's driver sorts its lasers so). A field holding laser ids
in firing order instead (a VLP-16's ids 0, 1, 2, ... alternate -15, +1, -13, ... deg)
puts rings 16 degrees apart side by side: on a simulated 16-beam lidar's 30 epochs
(random world 3, 2 cm noise) the ATE went from 0.003 m to 9.3 m (the height), no word.
The index pass sums each ring's point elevations in the sensor's frame (where a spinning
lidar's ring is a cone: one elevation); a topic is noted when its rings are cones (each
ring's elevation spread, its standard deviation, below half the median step between
neighbouring rings' mean elevations, which a Livox lidar's rosette lines are not) whose
means, in id order, neither rise nor fall throughout; unless the ids form runs of
:data:`MERGED_RUN` rings or more in elevation order (blocks: several lidars merged into one
cloud, left as they are), its ids are then given to its rings in elevation order (the same
ids, lowest beam first: :func:`ring_renumbering`), so the range image's rows are
neighbouring beams. No threshold fitted to data: the half step
separates a cone from its neighbours.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Rings in a row whose elevations rise (or fall) throughout that make a topic's ids blocks
#: of several lidars merged, not one lidar's lasers in firing order, which interleave its
#: beams (runs of 2 in a VLP-16's, at most 3 in a VLP-32C's); a judgment, not fitted.
MERGED_RUN = 4


@dataclass
class RingElevations:
    """Per ring id: points, sum of elevations and of their squares (rad)."""

    sums: dict[int, tuple[int, float, float]] = field(default_factory=dict)

    def add(self, points: np.ndarray, ring: np.ndarray) -> None:
        """One sweep's points (n, 3) in the sensor's frame and their ring ids (n,)."""
        if not len(ring):
            return
        elev = np.arctan2(points[:, 2], np.hypot(points[:, 0], points[:, 1]))
        lo = int(ring.min())
        key = ring.astype(np.int64) - lo
        if int(key.max()) >= 1 << 16:  # ids spread too far for a table: not a lidar's
            return
        n = np.bincount(key)
        s1 = np.bincount(key, weights=elev)
        s2 = np.bincount(key, weights=elev * elev)
        for i in np.flatnonzero(n):
            c, a, b = self.sums.get(int(i) + lo, (0, 0.0, 0.0))
            self.sums[int(i) + lo] = (c + int(n[i]), a + float(s1[i]), b + float(s2[i]))


def _means(
    rings: RingElevations, span: tuple[int, int] | None
) -> tuple[np.ndarray, np.ndarray] | None:
    """The ring ids (k,) and their mean elevations (k,) rad when the rings are cones whose
    means in id order neither rise nor fall throughout (module docstring), else None;
    ``span``: the ids kept, ``(first, last)`` (None: all; the others are no rings,
    :mod:`planodom.datasets.bag_rings`)."""
    first, last = span or (min(rings.sums, default=0), max(rings.sums, default=0))
    ids = np.array(sorted(i for i in rings.sums if first <= i <= last), dtype=np.int64)
    if len(ids) < 3:
        return None
    n, s1, s2 = (np.array([rings.sums[i][k] for i in ids], dtype=np.float64) for k in range(3))
    mean = s1 / n
    spread = np.sqrt(np.maximum(s2 / n - mean * mean, 0.0))
    step = float(np.median(np.diff(np.sort(mean))))
    steps = np.diff(mean)
    if step <= 0 or np.any(spread >= 0.5 * step) or np.all(steps > 0) or np.all(steps < 0):
        return None
    return ids, mean


def _longest_run(mean: np.ndarray) -> int:
    """The most rings (k,) in a row, in id order, whose mean elevations ``mean`` (k,) rise
    throughout or fall throughout."""
    up = np.diff(mean) > 0
    change = np.flatnonzero(up[1:] != up[:-1])
    bounds = np.concatenate([[-1], change, [len(up) - 1]])
    return int(np.diff(bounds).max()) + 1


def ring_renumbering(
    rings: RingElevations, span: tuple[int, int] | None = None
) -> tuple[np.ndarray, np.ndarray] | None:
    """``(ids (k,), new ids (k,))``: each ring id and the id its ring gets, the topic's ids
    in its rings' elevation order (lowest first), or None when its ids follow them
    (``span``: the ids kept, as :func:`_means`)."""
    found = _means(rings, span)
    if found is None or _longest_run(found[1]) >= MERGED_RUN:
        return None
    ids, mean = found
    new = np.empty_like(ids)
    new[np.argsort(mean, kind="stable")] = ids
    return ids, new


def ring_order_note(
    topic: str,
    rings: RingElevations,
    span: tuple[int, int] | None,
    subject: str = "topic",
    unread: str = "",
) -> str:
    """The note on a topic whose ring ids (those of ``span``) do not follow its beams'
    elevations, or ""; ``subject`` names what ``topic`` is (a dataset folder's scans:
    :mod:`planodom.datasets.folder_ring_order`), ``unread`` (when not "") why firing-order
    ids are read as they are instead of renumbered."""
    found = _means(rings, span)
    if found is None:
        return ""
    ids, mean = found
    run = _longest_run(mean)
    shown = ", ".join(f"{i}: {np.rad2deg(m):+.1f}" for i, m in zip(ids[:4], mean[:4], strict=False))
    return (
        f"{subject} '{topic}': its ring ids do not follow its beams' elevations (ring {shown}"
        f"{', ...' if len(ids) > 4 else ''} deg"
        + (
            f", runs of up to {run} rings in elevation order: several lidars merged?); read in "
            "id order, the range image's rows as those ids"
            if run >= MERGED_RUN
            else f": laser ids in firing order?); read in id order: {unread}"
            if unread
            else ": laser ids in firing order?); the same ids are given to its rings in "
            "elevation order, lowest first, so that the range image's neighbouring rows are "
            "neighbouring beams"
        )
    )
