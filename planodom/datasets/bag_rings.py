"""The ring ids of a bag's scan topic that cannot be rings of its lidar: :func:`ring_block`.

A lidar numbers its lasers consecutively (from 0, from 1 or from an offset such as 100),
so the ids a topic's points carry over a whole bag form one block, with holes only where
a laser returned nothing all along (a dead laser, one that sees only sky). Ids that are
not ring ids of that numbering are left out with their points (and noted), as the
"no ring" sentinel of an integer field is (:func:`planodom.datasets.bag_msgs.decode_sweep`):

- a negative id: no driver numbers its lasers below 0, and -1 is a signed field's
  "no ring";
- ids split from the others by a run of unused ids longer than the smaller side holds:
  for those few ids to be lasers of the same numbering, more lasers between them and
  the rest would have returned nothing over the whole bag than they themselves count
  (a stray 200 beside rings 0..15, or a float field's 65535.0, which has no type maximum
  to be the sentinel by). The rule has no tuned number: it compares the two sides'
  counts. Two equal sides (two lidars merged with a ring offset) are both kept.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np


def ring_counts(ring: np.ndarray) -> list[tuple[int, int]]:
    """``(id, points)`` of the ring ids (n,) present (a count, not a sort: cheap per sweep)."""
    lo, hi = int(ring.min()), int(ring.max())
    if hi - lo >= 1 << 16:  # ids spread too far for a table
        ids, counts = np.unique(ring, return_counts=True)
        return [(int(i), int(n)) for i, n in zip(ids, counts, strict=True)]
    counts = np.bincount(ring - lo)
    return [(int(i) + lo, int(counts[i])) for i in np.flatnonzero(counts)]


def ring_block(counts: Mapping[int, int]) -> tuple[int, int] | None:
    """``(first, last)`` ring ids kept of a topic's ``counts`` (id -> points over the bag),
    by the module docstring's rule; None without any id kept."""
    ids = np.array(sorted(i for i in counts if i >= 0), dtype=np.int64)
    lo, hi = 0, len(ids) - 1  # the kept ids: ids[lo..hi]
    while hi > lo:
        k = np.arange(lo, hi)  # the run of unused ids after ids[k]
        unused = ids[k + 1] - ids[k] - 1
        left, right = k - lo + 1, hi - k
        split = (unused > np.minimum(left, right)) & (left != right)
        if not split.any():
            break
        smaller = np.minimum(left, right)
        j = int(k[split][np.argmin(smaller[split])])  # drop the fewest ids first
        if j - lo + 1 < hi - j:
            lo = j + 1
        else:
            hi = j
    if hi < lo:
        return None
    return int(ids[lo]), int(ids[hi])


def stray_span(counts: Mapping[int, int]) -> tuple[int, int] | None:
    """The ring ids kept, ``(first, last)``, when some of ``counts`` (id -> points) are not
    (``(0, -1)``: none is); None when all are."""
    if not counts:
        return None
    block = ring_block(counts)
    if block == (min(counts), max(counts)):
        return None
    return block or (0, -1)


def stray_note(topic: str, counts: Mapping[int, int], block: tuple[int, int] | None) -> str:
    """The note on the points of ``counts`` whose ids lie outside ``block``, or ""."""
    first, last = block or (0, -1)
    stray = sorted(i for i in counts if not first <= i <= last)
    if not stray:
        return ""
    points = sum(counts[i] for i in stray)
    shown = ", ".join(str(i) for i in stray[:5]) + (", ..." if len(stray) > 5 else "")
    kept = f"its rings {first}..{last}" if last >= first else "no ring"
    ids = f"{len(stray)} id{'s' if len(stray) > 1 else ''}"
    return (
        f"topic '{topic}': {points} points carry ring ids that are no ring of its lidar's "
        f"numbering beside {kept} ({ids}: {shown}; negative, or apart from the others by "
        "more unused ids than they count); left out"
    )
