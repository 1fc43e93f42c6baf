"""The RANSAC fallback's cluster helpers against scipy, a per-label selection and numpy."""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from planodom.extraction.lidar.candidates import _buckets, _seam_components, _tls_normal, _within
from planodom.extraction.planes.fit import tls_fit


def test_seam_components_number_as_scipy():
    rng = np.random.default_rng(3)
    for _ in range(500):
        n = int(rng.integers(1, 30))
        k = int(rng.integers(0, 25))
        a, b = rng.integers(0, n, k), rng.integers(0, n, k)
        graph = coo_matrix((np.ones(k), (a, b)), shape=(n, n))
        _, expected = connected_components(graph, directed=False)
        np.testing.assert_array_equal(_seam_components(n, a, b), expected)


def test_buckets_equal_one_selection_per_label():
    rng = np.random.default_rng(4)
    label = rng.integers(-1, 6, 300)
    idx = np.flatnonzero(rng.random(300) < 0.7)
    members, bounds = _buckets(idx, label[idx], 7)
    assert len(bounds) == 8
    for lab in range(7):
        got = members[bounds[lab] : bounds[lab + 1]]
        np.testing.assert_array_equal(got, idx[label[idx] == lab])
    members, bounds = _buckets(idx[:0], label[:0], 3)
    assert len(members) == 0
    np.testing.assert_array_equal(bounds, [0, 0, 0, 0])


def test_compiled_fit_and_selection_match_numpy():
    rng = np.random.default_rng(5)
    for _ in range(50):
        n_true = rng.normal(size=3)
        n_true /= np.linalg.norm(n_true)
        pts = rng.uniform(-20, 20, (400, 3))
        pts -= np.outer(pts @ n_true + rng.uniform(-5, 5), n_true)  # onto a plane
        pts += rng.normal(0, 0.02, (400, 1)) * n_true
        idx = np.sort(rng.choice(400, 150, replace=False))
        c, n = _tls_normal(pts, idx)
        c_np, _, ev = tls_fit(pts[idx])
        np.testing.assert_allclose(c, c_np, rtol=0, atol=1e-12)
        assert abs(abs(n @ ev[:, 2]) - 1.0) < 1e-12
        expected = idx[np.abs((pts[idx] - c_np) @ ev[:, 2]) <= 0.02]
        np.testing.assert_array_equal(_within(pts, idx, c, n, 0.02), expected)
