"""Decimation of a dense lidar's organised image (``grid_max_columns``, ``grid_max_rows``):
the points kept against an independent count of rows and columns, and the planes of a
decimated scan against the true walls and the undecimated extraction."""

from __future__ import annotations

import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction import extract
from planodom.extraction.lidar.decimate import kept_points

from .synth_scans import default_scene, planes_in_base, scan_lidar

SCENE = default_scene()
TRUTH = planes_in_base(SCENE)


def test_kept_points_are_every_kth_row_and_column():
    n_beams, n_az = 16, 1024
    scan = scan_lidar(SCENE, n_beams=n_beams, n_azimuth=n_az)
    # the simulated lidar's own grid: ring = beam, column = firing (time step)
    col = np.rint(scan.t / (0.1 / n_az)).astype(np.int64)
    col -= col.min()
    for max_cols, max_rows, k_col, k_row in ((512, None, 2, 1), (300, 8, 4, 2), (None, 5, 1, 4)):
        keep = kept_points(scan.ring, scan.t, max_cols, max_rows)
        expected = np.flatnonzero((col % k_col == 0) & (scan.ring % k_row == 0))
        np.testing.assert_array_equal(keep, expected)
    assert kept_points(scan.ring, scan.t, 1024, 16) is None  # within the limits
    assert kept_points(scan.ring, scan.t, None, None) is None
    assert kept_points(scan.ring, np.zeros(len(scan)), 16, 4) is None  # no columns: no grid


def test_decimated_extraction_finds_the_walls_with_whole_scan_indices():
    sigma = 0.005
    scan = scan_lidar(SCENE, sigma=sigma, n_beams=32, n_azimuth=2048)
    full = extract(scan, ExtractionConfig(range_noise_m=sigma))
    config = ExtractionConfig(range_noise_m=sigma, grid_max_columns=1024, grid_max_rows=16)
    dec = extract(scan, config)
    keep = kept_points(scan.ring, scan.t, 1024, 16)
    assert keep is not None and len(keep) < len(scan) / 3
    assert {p.truth_id for p in dec.planes} == {p.truth_id for p in full.planes} == set(TRUTH)
    for p, inl in zip(dec.planes, dec.inliers, strict=True):
        assert np.isin(inl, keep).all()  # indices of the whole scan, kept points only
        assert (scan.label[inl] == p.truth_id).mean() > 0.95
        n, d = TRUTH[p.truth_id]
        assert np.linalg.norm(np.cross(p.normal, n)) < 5 * np.sqrt(np.trace(p.covariance[:3, :3]))
        assert abs(p.offset - d) < 5 * np.sqrt(p.covariance[3, 3]) + 1e-3
