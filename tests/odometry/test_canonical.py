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
