"""The RANSAC fallback's cluster helpers against scipy and a per-label selection."""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from planodom.extraction.lidar.candidates import _groups, _seam_components


def test_seam_components_number_as_scipy():
    rng = np.random.default_rng(3)
    for _ in range(500):
        n = int(rng.integers(1, 30))
        k = int(rng.integers(0, 25))
        a, b = rng.integers(0, n, k), rng.integers(0, n, k)
        graph = coo_matrix((np.ones(k), (a, b)), shape=(n, n))
        _, expected = connected_components(graph, directed=False)
        np.testing.assert_array_equal(_seam_components(n, a, b), expected)


def test_groups_equal_one_selection_per_label():
    rng = np.random.default_rng(4)
    label = rng.integers(-1, 6, 300)
    idx = np.flatnonzero(rng.random(300) < 0.7)
    groups = _groups(idx, label[idx])
    expected = {int(v): idx[label[idx] == v] for v in np.unique(label[idx]) if v >= 0}
    assert groups.keys() == expected.keys()
    for key, members in expected.items():
        np.testing.assert_array_equal(groups[key], members)
    assert _groups(idx[:0], label[:0]) == {}
