"""Unorganised lidar clouds (no ring, no time): scan rows recovered from the points, and
planes on the recovered range image."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import ExtractionConfig
from planodom.extraction import extract
from planodom.extraction.lidar.rows import elevation_rows, ring_major_rows, scan_rows
from planodom.scan import Scan

from .synth_scans import default_scene, planes_in_base, rect, scan_lidar

SCENE = default_scene()
TRUTH = planes_in_base(SCENE)
HEIGHT = 1.8  # the synthetic lidar's origin above the base origin


def _same_partition(rows: np.ndarray, ring: np.ndarray) -> bool:
    """Rows label the rings one to one (in any order)."""
    pairs = np.unique(np.column_stack([rows, ring]), axis=0)
    return len(pairs) == len(np.unique(rows)) == len(np.unique(ring))


def test_elevation_rows_of_a_column_major_cloud_are_its_rings():
    scan = scan_lidar(SCENE, n_azimuth=512)
    found = scan_rows(scan.points, np.array([0, 0, HEIGHT]))
    assert found is not None
    rows, mode = found
    assert mode == "elevation" and _same_partition(rows, scan.ring)
    # Lowest beam first.
    assert np.all(np.diff([np.median(scan.ring[rows == r]) for r in np.unique(rows)]) > 0)


def test_rows_need_the_sensor_origin():
    """Seen from the base origin, 1.8 m below the sensor, elevations are not constant per
    beam and the modes smear: the rows found are not the rings."""
    scan = scan_lidar(SCENE, n_azimuth=512)
    found = scan_rows(scan.points)
    assert found is None or not _same_partition(found[0], scan.ring)


def test_ring_major_rows_follow_the_file_order():
    scan = scan_lidar(SCENE, n_azimuth=512)
    order = np.argsort(scan.ring, kind="stable")  # one beam's revolution after the other
    pts = scan.points[order] - [0, 0, HEIGHT]
    rows = ring_major_rows(pts)
    assert rows is not None
    assert _same_partition(rows, scan.ring[order]) and np.all(np.diff(rows) >= 0)
    # A shuffled cloud is not ring-major, but its elevations still give the rings.
    perm = np.random.default_rng(0).permutation(len(pts))
    assert ring_major_rows(pts[perm]) is None
    assert _same_partition(elevation_rows(pts[perm]), scan.ring[order][perm])


def test_a_cloud_without_beams_has_no_rows():
    rng = np.random.default_rng(1)
    assert scan_rows(rng.normal(size=(5000, 3)) * 10) is None


def test_unorganised_cloud_gives_the_walls_with_moments():
    scan = scan_lidar(SCENE, n_azimuth=1024, with_ring=False)
    bare = Scan(scan.points, None, None, scan.label)
    res = extract(bare, ExtractionConfig(), sensor_origins=np.array([0, 0, HEIGHT]))
    assert res.mode == "lidar"
    assert {p.truth_id for p in res.planes} == set(TRUTH)
    for p, idx in zip(res.planes, res.inliers, strict=True):
        n, d = TRUTH[p.truth_id]
        assert np.degrees(np.arccos(np.clip(p.normal @ n, -1, 1))) < 0.05
        assert abs(p.offset - d) < 0.01
        sup = p.support
        P = bare.points[idx]
        assert sup.n_points == len(idx) and sup.n_rows >= 2
        np.testing.assert_allclose(sup.scatter, (P - P.mean(0)).T @ (P - P.mean(0)), atol=1e-6)
    # One plane per wall: coplanar pieces merged.
    ids = [p.truth_id for p in res.planes]
    assert len(ids) == len(set(ids))
    again = extract(bare, ExtractionConfig(), sensor_origins=np.array([0, 0, HEIGHT]))
    for a, b in zip(res.planes, again.planes, strict=True):
        np.testing.assert_array_equal(a.coefficients, b.coefficients)


def test_a_cloud_with_times_but_no_ring_is_extracted_as_with_its_ring():
    """Recovered rows and times are what a ring field gives: the same planes as the scan
    with its ring (a sparse 16-beam lidar, whose square-pixel image is 2 deg wide)."""
    scan = scan_lidar(SCENE, n_beams=16, n_azimuth=1024)
    origin = np.array([0, 0, HEIGHT])
    # Coplanar pieces merged across the walls between them (region_merge: reach): the
    # ground's stretches between the walls are one plane in both; elevation modes move a
    # few ground points to another row, so its size, and the order, may differ.
    cfg = ExtractionConfig(region_merge="reach")
    ringed = extract(scan, cfg, sensor_origins=origin)
    bare = extract(Scan(scan.points, None, scan.t, scan.label), cfg, sensor_origins=origin)
    assert {p.truth_id for p in ringed.planes} == set(TRUTH)
    assert sorted(p.truth_id for p in bare.planes) == sorted(TRUTH)
    assert len(ringed.planes) == len(TRUTH)
    by_id = {p.truth_id: p for p in bare.planes}
    for a in ringed.planes:
        b = by_id[a.truth_id]
        np.testing.assert_allclose(a.coefficients, b.coefficients, atol=1e-12)
        # Elevation modes put a few of a beam's points (0.3 %) in the row below.
        assert abs(a.support.n_rows - b.support.n_rows) <= 1 and b.support.n_rows >= 2


def _corridor() -> list:
    """A corridor 4 m wide and 40 m long, floor z = 0 (id 0), ceiling z = 3.6 (id 1),
    for a lidar 1.8 m above the floor (the base origin on it)."""
    return [
        rect([0, 0, 0], [0, 0, 1], up=[1, 0, 0], half_u=2, half_v=20),
        rect([0, 0, 3.6], [0, 0, -1], up=[1, 0, 0], half_u=2, half_v=20),
        rect([0, 2, 1.8], [0, -1, 0], half_u=20, half_v=1.8),
        rect([0, -2, 1.8], [0, 1, 0], half_u=20, half_v=1.8),
        rect([20, 0, 1.8], [-1, 0, 0], half_u=2, half_v=1.8),
        rect([-20, 0, 1.8], [1, 0, 0], half_u=2, half_v=1.8),
    ]


@pytest.mark.parametrize("times", [True, False])
def test_a_sparse_ringless_lidar_keeps_floor_and_ceiling(times):
    """A 16-beam lidar's rows are 2 deg apart: on the floor of a corridor they are metres
    apart (1.2 m between the second and third row here), more than the gap rule allows
    consecutive points of a scan line at that range. Floor and ceiling are still found,
    with their normals towards the sensor, with times (recovered rows as the ring) and
    without (square-pixel image, ``organised_gap: incidence``)."""
    walls = _corridor()
    scan = scan_lidar(walls, sigma=0.006, n_beams=16, n_azimuth=1024, with_ring=False)
    bare = Scan(scan.points, None, scan.t if times else None, scan.label)
    # without times: the square-pixel image, whose incidence rule is not the default
    cfg = ExtractionConfig() if times else ExtractionConfig(organised_gap="incidence")
    res = extract(bare, cfg, sensor_origins=np.array([0, 0, HEIGHT]))
    truth = planes_in_base(walls)
    found = {p.truth_id for p in res.planes}
    assert {0, 1, 2, 3} <= found  # floor, ceiling, both long walls
    for p in res.planes:  # the true normals point towards the sensor already
        n, d = truth[p.truth_id]
        assert np.degrees(np.arccos(np.clip(p.normal @ n, -1, 1))) < 0.5
        assert abs(p.offset - d) < 0.02
