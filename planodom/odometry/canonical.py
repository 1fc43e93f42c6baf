"""The canonical order of a plane set: the solver sorts both epochs' planes by their values,
so that the order they were extracted in cannot change a relative pose."""

from __future__ import annotations

import weakref

import numpy as np

from planodom.planes import PlaneSet

#: The canonical order and the ordered set of the plane sets solved lately, by identity
#: (a streaming odometry solves each epoch's set about four times: against its reference
#: with each extraction of the next epoch, and as the next epoch's reference). Plane sets
#: are frozen and their arrays not changed in place (as :mod:`planodom.extraction.memo`).
_CANONICAL: weakref.WeakKeyDictionary[PlaneSet, tuple[np.ndarray, PlaneSet]] = (
    weakref.WeakKeyDictionary()
)


def canonical(planes: PlaneSet) -> tuple[np.ndarray, PlaneSet]:
    """:func:`canonical_order` of ``planes`` and the planes in that order (remembered)."""
    known = _CANONICAL.get(planes)
    if known is None:
        order = canonical_order(planes)
        known = _CANONICAL[planes] = (order, planes.take(order))
    return known


def canonical_order(planes: PlaneSet) -> np.ndarray:
    """A permutation sorting planes by their values, so the input order cannot matter."""
    n, c = planes.normals, planes.centroids
    # the columns (n, d, weight, centroid, radius), the first the primary key (lexsort's
    # last), given as columns: no stacked copy of them
    keys = (planes.radii, c[:, 2], c[:, 1], c[:, 0], planes.weights, planes.offsets)
    return np.lexsort(keys + (n[:, 2], n[:, 1], n[:, 0]))
