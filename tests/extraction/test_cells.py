"""The RANSAC fallback's angular cells (:mod:`planodom.extraction.lidar.cells`) against
the numpy formula and one selection per cell."""

from __future__ import annotations

import numpy as np

from planodom.extraction.lidar.cells import angular_cells, cell_index, cell_members


def _formula(points, view, cell_deg):
    """The cells written out with numpy: floor((atan2 + offset) / cell), per column."""
    rel = points - view
    az = np.arctan2(rel[:, 1], rel[:, 0])
    el = np.arctan2(rel[:, 2], np.hypot(rel[:, 0], rel[:, 1]))
    cell = np.radians(cell_deg)
    return np.floor((az + np.pi) / cell).astype(np.int64), np.floor((el + np.pi / 2) / cell).astype(
        np.int64
    )


def _edge_points(cell_deg):
    """Points at azimuths and elevations on the cells' edges, one ulp around them, at the
    seam (-pi, +pi, signed zeros) and straight up and down."""
    k = np.arange(0, 360, cell_deg)
    ang = np.radians(np.concatenate([k, k]) - 180.0)
    ang = np.concatenate([ang, np.nextafter(ang, 4.0), np.nextafter(ang, -4.0)])
    ring = np.column_stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)])
    el = np.radians(np.arange(-90, 91, cell_deg))
    el = np.concatenate([el, np.nextafter(el, 2.0), np.nextafter(el, -2.0)])
    fan = np.column_stack([np.cos(el), np.zeros_like(el), np.sin(el)])
    seam = np.array([[-1.0, 0.0, 0.0], [-1.0, -0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    return np.vstack([3.0 * ring, 7.0 * fan, seam, [[0.0, 0.0, 0.0]]])


def test_cell_index_equals_the_formula_and_angular_cells():
    rng = np.random.default_rng(11)
    for cell_deg in (3.0, 1.0, 7.5, 0.7):
        n_az = int(np.ceil(360.0 / cell_deg))
        view = np.array([0.3, -0.2, 1.8])
        pts = np.vstack([rng.normal(scale=10.0, size=(5000, 3)) + view,
                         _edge_points(cell_deg) + view])  # fmt: skip
        az, el = cell_index(pts, view, cell_deg, n_az)
        want_az, want_el = _formula(pts, view, cell_deg)
        np.testing.assert_array_equal(az, want_az % n_az)
        np.testing.assert_array_equal(el, want_el)
        np.testing.assert_array_equal(angular_cells(pts, view, cell_deg), np.column_stack(
            [want_az, want_el]))  # fmt: skip
        assert az.flags.c_contiguous and el.flags.c_contiguous
        assert az.min() >= 0 and az.max() < n_az and el.min() >= 0


def test_cell_members_equal_one_selection_per_cell():
    rng = np.random.default_rng(12)
    n_az, n_el = 9, 5
    az, el = rng.integers(0, n_az, 400), rng.integers(0, n_el, 400)
    idx, bounds = cell_members(az, el, n_az, n_el)
    assert len(bounds) == n_az * n_el + 1
    for a in range(n_az):
        for e in range(n_el):
            key = a * n_el + e
            got = idx[bounds[key] : bounds[key + 1]]
            np.testing.assert_array_equal(got, np.flatnonzero((az == a) & (el == e)))
