"""The RANSAC fallback's compiled helpers against scipy, one selection per label and numpy."""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from planodom.extraction.lidar.candidates import _tls_normal, _within
from planodom.extraction.lidar.cells import cell_members
from planodom.extraction.lidar.clusters import (
    buckets,
    cell_buckets,
    clusters,
    region_buckets,
)
from planodom.extraction.lidar.ransac import distinct_triples
from planodom.extraction.planes.fit import tls_fit


def _clusters_scipy(cells, n_az):
    """The clusters by scipy: ndimage.label, the clusters joined across the azimuth seam
    as a sparse graph, ndimage.grey_dilation on the grid padded by wrapping."""
    n_el = int(cells[:, 1].max()) + 2
    grid = np.zeros((n_az, n_el), dtype=bool)
    grid[cells[:, 0] % n_az, cells[:, 1]] = True
    labels, n_lab = ndimage.label(grid, structure=np.ones((3, 3), dtype=bool))
    first, last = labels[0], labels[-1]
    a = np.concatenate([first[:-1], first, first[1:]])
    b = np.concatenate([last[1:], last, last[:-1]])
    seam = (a > 0) & (b > 0)
    shape = (n_lab + 1, n_lab + 1)
    graph = coo_matrix((np.ones(np.count_nonzero(seam)), (a[seam], b[seam])), shape=shape)
    _, comp = connected_components(graph, directed=False)
    merged = np.where(labels > 0, comp[labels], -1)
    padded = np.vstack([merged[-1:], merged, merged[:1]])
    dilated = ndimage.grey_dilation(padded, size=(3, 3))[1:-1]
    lookup = np.where(merged < 0, dilated, merged)
    return merged[cells[:, 0] % n_az, cells[:, 1]], lookup


def test_clusters_match_scipy():
    rng = np.random.default_rng(3)
    for _ in range(300):
        n_az = int(rng.integers(4, 40))
        k = int(rng.integers(1, 200))
        cells = np.column_stack([rng.integers(-n_az, 2 * n_az, k), rng.integers(0, 12, k)])
        labels, lookup = clusters(cells, n_az)
        expected_labels, expected_lookup = _clusters_scipy(cells, n_az)
        np.testing.assert_array_equal(labels, expected_labels)
        np.testing.assert_array_equal(lookup, expected_lookup)


def test_clusters_match_scipy_away_from_the_lowest_elevation():
    """The grid is built from the lowest occupied elevation cell on (a window): the same
    labels and lookup as scipy's on the whole grid."""
    rng = np.random.default_rng(8)
    for _ in range(200):
        n_az = int(rng.integers(4, 40))
        k = int(rng.integers(1, 120))
        low = int(rng.integers(0, 30))
        cells = np.column_stack([rng.integers(0, n_az, k), low + rng.integers(0, 6, k)])
        labels, lookup = clusters(cells, n_az)
        expected_labels, expected_lookup = _clusters_scipy(cells, n_az)
        np.testing.assert_array_equal(labels, expected_labels)
        np.testing.assert_array_equal(lookup, expected_lookup)


def test_buckets_equal_one_selection_per_label():
    rng = np.random.default_rng(4)
    label = rng.integers(-1, 6, 300)
    idx = np.flatnonzero(rng.random(300) < 0.7)
    members, bounds = buckets(idx, label[idx], 7)
    assert len(bounds) == 8
    for lab in range(7):
        got = members[bounds[lab] : bounds[lab + 1]]
        np.testing.assert_array_equal(got, idx[label[idx] == lab])
    members, bounds = buckets(idx[:0], label[:0], 3)
    assert len(members) == 0
    np.testing.assert_array_equal(bounds, [0, 0, 0, 0])


def test_region_buckets_equal_the_numpy_gather_and_buckets():
    """The compiled counting sort gives the RANSAC loop's (members, bounds) of the points
    not taken by their dilated cluster exactly as the numpy gather and _buckets did."""
    rng = np.random.default_rng(6)
    for _ in range(20):
        n_az, n_el, n = 40, int(rng.integers(3, 9)), 2000
        lookup = rng.integers(-1, 5, (n_az, n_el))
        az, el = rng.integers(0, n_az, n), rng.integers(0, n_el + 4, n)  # some above top
        taken = rng.random(n) < 0.3
        n_lab = int(lookup.max()) + 1
        free = np.flatnonzero(~taken)
        top = n_el - 1
        expected = buckets(free, lookup[az[free], np.minimum(el[free], top)], n_lab)
        got = region_buckets(az, el, taken, lookup, n_lab)
        np.testing.assert_array_equal(got[0], expected[0])
        np.testing.assert_array_equal(got[1], expected[1])


def test_cell_buckets_equal_the_numpy_gather_and_buckets():
    """Visiting only the angular cells with a cluster gives the same (members, bounds) as
    the numpy gather over every point, with the lookup grid's rows from ``lo`` on and the
    points above its top row in that row's cells; windows reaching above the points'
    elevations too."""
    rng = np.random.default_rng(9)
    for _ in range(60):
        n_az, n_win, n, lo = 40, int(rng.integers(1, 9)), 2000, int(rng.integers(0, 5))
        window = rng.integers(-1, 5, (n_az, n_win))
        window[rng.random(n_az) < 0.6] = -1  # most azimuth cells without a cluster
        n_el = int(rng.integers(1, lo + n_win + 5))  # the points' elevations: [0, n_el)
        az, el = rng.integers(0, n_az, n), rng.integers(0, n_el, n)
        taken = rng.random(n) < 0.3
        n_lab = int(window.max()) + 1
        lookup = np.hstack([np.full((n_az, lo), -1), window])  # rows below lo free
        free = np.flatnonzero(~taken)
        top = lo + n_win - 1
        expected = buckets(free, lookup[az[free], np.minimum(el[free], top)], n_lab)
        cell_idx, cell_b = cell_members(az, el, n_az, n_el)
        got = cell_buckets(cell_idx, cell_b, n_el, taken, window, lo, n_lab)
        np.testing.assert_array_equal(got[0], expected[0])
        np.testing.assert_array_equal(got[1], expected[1])


def test_distinct_triples_cover_every_ordered_triple_once():
    """Every raw draw (a < m, b < m - 1, c < m - 2) gives a triple of distinct indices,
    and all m (m - 1) (m - 2) ordered triples come out once (so each is uniform)."""
    for m in (3, 4, 7):
        raw = np.array(
            [(a, b, c) for a in range(m) for b in range(m - 1) for c in range(m - 2)],
            dtype=np.int64,
        )
        out = distinct_triples(raw)
        assert all(len(set(t)) == 3 and max(t) < m for t in out.tolist())
        assert len({tuple(t) for t in out.tolist()}) == m * (m - 1) * (m - 2)


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
