"""The solver's canonical order of a plane set, remembered per set."""

from __future__ import annotations

import numpy as np

from planodom.odometry.canonical import canonical, canonical_order
from planodom.planes import PlaneSet


def _set(rng: np.random.Generator, k: int) -> PlaneSet:
    n = rng.normal(size=(k, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    cov = np.broadcast_to(np.eye(4) * 1e-4, (k, 4, 4)).copy()
    return PlaneSet(n, rng.normal(size=k), rng.uniform(0.1, 1, k), rng.normal(size=(k, 3)),
                    rng.uniform(1, 5, k), cov)  # fmt: skip


def test_canonical_sorts_by_values_whatever_the_input_order_and_remembers_the_set():
    rng = np.random.default_rng(5)
    planes = _set(rng, 7)
    order, ordered = canonical(planes)
    # the first normal component sorts first (lexsort over all values)
    assert np.all(np.diff(ordered.normals[:, 0]) >= 0)
    np.testing.assert_array_equal(ordered.offsets, planes.offsets[order])
    # a shuffled copy of the same planes: the same canonical planes
    perm = rng.permutation(7)
    shuffled = planes.take(perm)
    _, ordered2 = canonical(shuffled)
    np.testing.assert_array_equal(ordered2.normals, ordered.normals)
    np.testing.assert_array_equal(ordered2.covariances, ordered.covariances)
    # asked again for the same set: the remembered order and set
    again = canonical(planes)
    assert again[1] is ordered and again[0] is order
    np.testing.assert_array_equal(canonical_order(planes), order)


def test_canonical_order_is_the_lexsort_of_the_stacked_values_ties_included():
    """Against the values stacked into one (K, 9) table and sorted row by row (column 0
    first): ties in the normals (a plane repeated, one with a NaN radius) are broken by
    the later columns in the same way."""
    rng = np.random.default_rng(8)
    for _ in range(50):
        planes = _set(rng, 6)
        rep = planes.take(np.array([0, 1, 2, 0, 4, 0]))
        radii = rep.radii.copy()
        radii[3] = np.nan
        rep = PlaneSet(rep.normals, rep.offsets, rep.weights, rep.centroids, radii,
                       rep.covariances)  # fmt: skip
        for s in (planes, rep):
            table = np.column_stack([s.normals, s.offsets, s.weights, s.centroids, s.radii])
            rows = [tuple(r) for r in table.tolist()]
            # Python's sort of the rows (NaN last, as numpy sorts it): an independent order
            key = [tuple((np.isnan(v), 0.0 if np.isnan(v) else v) for v in r) for r in rows]
            expected = sorted(range(len(rows)), key=lambda i: key[i])
            np.testing.assert_array_equal(canonical_order(s), expected)
