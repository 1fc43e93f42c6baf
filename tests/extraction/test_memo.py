"""The identity memo (:mod:`planodom.extraction.memo`) and what it lets a re-extraction of
the same scan reuse."""

from __future__ import annotations

import gc

import numpy as np
import pytest

from planodom.config import ExtractionConfig
from planodom.errors import GeometryError
from planodom.extraction import extract
from planodom.extraction.memo import identity_memo, read_only
from planodom.scan import Scan

from .synth_scans import default_scene, scan_lidar, scan_rig


def test_memo_returns_the_last_result_for_the_same_arrays_only():
    calls = []

    @identity_memo
    def total(a, scale):
        calls.append(1)
        return float(a.sum()) * scale

    a = np.arange(4.0)
    assert total(a, 2.0) == 12.0
    assert total(a, 2.0) == 12.0 and len(calls) == 1  # same array, same scalar
    assert total(a.copy(), 2.0) == 12.0 and len(calls) == 2  # equal but another array
    assert total(a, 3.0) == 18.0 and len(calls) == 3  # another scalar
    assert total(a, 3) == 18.0 and len(calls) == 4  # another type
    # a new array after the remembered one was freed is not mistaken for it
    b = np.ones(3)
    total(b, 1.0)
    n = len(calls)
    del b
    gc.collect()
    assert total(np.full(3, 2.0), 1.0) == 6.0 and len(calls) == n + 1


def test_memo_does_not_remember_a_failure():
    calls = []

    @identity_memo
    def check(a):
        calls.append(1)
        if not np.isfinite(a).all():
            raise ValueError("not finite")

    a = np.array([1.0, np.nan])
    for _ in range(2):
        with pytest.raises(ValueError):
            check(a)
    assert len(calls) == 2


def test_read_only_results_cannot_be_changed_by_a_caller():
    a = read_only(np.zeros(3))
    with pytest.raises(ValueError):
        a[0] = 1.0


def test_a_second_extraction_of_the_same_scan_equals_one_of_a_fresh_copy():
    """The odometry extracts a scan again with another twist: reusing what depends on the
    rings and times alone must give what an extraction from scratch (new arrays) gives."""
    scan = scan_rig(default_scene(), twist=np.array([0, 0, 0.4, 1.5, 0.2, 0]), sigma=0.005)
    fresh = Scan(scan.points.copy(), scan.ring.copy(), scan.t.copy(), scan.label.copy())
    twists = [np.array([0, 0, 0.3, 1.2, 0, 0]), np.array([0, 0, 0.4, 1.5, 0.2, 0])]
    extract(scan, twist=twists[0])
    again = extract(scan, twist=twists[1])  # rings and times as remembered
    scratch = extract(fresh, twist=twists[1])
    assert len(again.planes) == len(scratch.planes) > 0
    for p, q in zip(again.planes, scratch.planes, strict=True):
        np.testing.assert_array_equal(p.normal, q.normal)
        assert p.offset == q.offset
    for i, j in zip(again.inliers, scratch.inliers, strict=True):
        np.testing.assert_array_equal(i, j)


def _same_planes(a, b) -> None:
    assert len(a.planes) == len(b.planes) > 0
    for p, q in zip(a.planes, b.planes, strict=True):
        np.testing.assert_array_equal(p.normal, q.normal)
        assert p.offset == q.offset
        np.testing.assert_array_equal(p.covariance, q.covariance)
    for i, j in zip(a.inliers, b.inliers, strict=True):
        np.testing.assert_array_equal(i, j)


@pytest.mark.parametrize(
    "change", [{"twist_rate_sigma_deg_s": 6.0}, {"split_sigma_factor": 2.0, "min_gap_m": 0.3}]
)
def test_a_rig_scan_extracted_again_with_the_same_twist_equals_a_fresh_copy(change):
    """An epoch lost with its tolerances is extracted again with the same twist and wider
    ones (the odometry's ``widened_if_lost``): the deskewed points are reused (the same
    array), and the segments only when the fields they depend on are the same; either
    way the planes are those of an extraction of new arrays with that config."""
    scan = scan_rig(default_scene(), twist=np.array([0, 0, 0.4, 1.5, 0.2, 0]), sigma=0.005)
    fresh = Scan(scan.points.copy(), scan.ring.copy(), scan.t.copy(), scan.label.copy())
    twist, cfg = np.array([0, 0, 0.3, 1.2, 0, 0]), ExtractionConfig()
    other = cfg.model_copy(update=change)
    first = extract(scan, cfg, twist=twist)
    again = extract(scan, other, twist=twist.copy())
    assert again.points is first.points and not again.points.flags.writeable
    _same_planes(again, extract(fresh, other, twist=twist))
    _same_planes(extract(scan, cfg, twist=twist), extract(fresh, cfg, twist=twist))


def test_checked_origins_are_remembered_per_scan_and_array_only():
    """The rig's origins are checked once per scan (memoised by identity): a second
    extraction equals the first, the caller's array is left writeable, and other origins
    for the same scan are checked anew (too few for its rings: refused)."""
    scan = scan_rig(default_scene(), sigma=0.005)
    n_rings = int(scan.ring.max()) + 1
    origins = np.tile([0.0, 0.0, 0.5], (n_rings, 1))
    origins[:, 0] = np.arange(n_rings) * 0.1  # distinct: per-ring origins
    first = extract(scan, sensor_origins=origins)
    second = extract(scan, sensor_origins=origins)
    assert len(first.planes) == len(second.planes) > 0
    for p, q in zip(first.planes, second.planes, strict=True):
        np.testing.assert_array_equal(p.normal, q.normal)
    assert origins.flags.writeable
    with pytest.raises(GeometryError, match="do not index"):
        extract(scan, sensor_origins=origins[:-1].copy())


@pytest.mark.parametrize("with_ring", [True, False])
def test_a_lidar_scan_extracted_again_equals_a_fresh_copy(with_ring):
    """The lidar path reuses its grid, ring order and (without a ring field) recovered rows
    across an epoch's extractions: the second of two extractions with different twists
    equals an extraction of new arrays with the second twist."""
    scan = scan_lidar(default_scene(), np.array([0, 0, 0.3, 1.5, 0, 0]), 0.005, n_azimuth=512,
                      with_ring=with_ring)  # fmt: skip
    fresh = Scan(scan.points.copy(), None if scan.ring is None else scan.ring.copy(),
                 scan.t.copy(), scan.label.copy())  # fmt: skip
    twists = [np.array([0, 0, 0.2, 1.0, 0, 0]), np.array([0, 0, 0.3, 1.5, 0, 0])]
    extract(scan, twist=twists[0])
    again = extract(scan, twist=twists[1])
    scratch = extract(fresh, twist=twists[1])
    assert len(again.planes) == len(scratch.planes) > 0
    for p, q in zip(again.planes, scratch.planes, strict=True):
        np.testing.assert_array_equal(p.coefficients, q.coefficients)
    for i, j in zip(again.inliers, scratch.inliers, strict=True):
        np.testing.assert_array_equal(i, j)


def test_memo_tells_an_array_from_a_value_in_the_same_place():
    calls = []

    @identity_memo
    def first(x):
        calls.append(1)
        return x

    a = np.zeros(2)
    first(a)
    first(None)  # a value where an array was
    first(a)  # an array where a value was
    first((1.0, float("nan")))
    n = len(calls)
    nan_key = (1.0, float("nan"))
    first(nan_key)  # an equal-looking value that does not compare equal: computed again
    assert len(calls) == n + 1 == 5
    first(nan_key)  # the very same tuple (equal to itself, as a tuple): remembered
    assert len(calls) == 5


def test_the_agreement_check_reuses_the_range_images_grid_of_deskewed_points(monkeypatch):
    """Deskewed points are an array numba allocated, of which ``np.ascontiguousarray(a,
    dtype=np.float64)`` makes a new view on every call: the RANSAC agreement check's
    grid (and pixel normals) must still be the range image's of the same points, built
    once (``float64_c`` passes the array itself)."""
    import planodom.extraction.lidar.grid as grid
    from planodom.extraction.deskew import deskew_points
    from planodom.extraction.lidar.agreement import point_normals
    from planodom.extraction.lidar.rangeimage import range_image_candidates
    from planodom.extraction.memo import float64_c

    scan = scan_lidar(default_scene(), np.array([0, 0, 0.3, 1.5, 0, 0]), 0.005, n_azimuth=512)
    points = deskew_points(scan.points, scan.t, np.array([0, 0, 0.3, 1.5, 0, 0]))
    assert float64_c(points) is points
    assert float64_c(points.astype(np.float32)).dtype == np.float64
    built = []
    fill = grid.fill_grid
    monkeypatch.setattr(grid, "fill_grid", lambda *a: built.append(1) or fill(*a))
    cfg = ExtractionConfig()
    range_image_candidates(points, scan.ring, scan.t, 0.005, cfg, np.zeros(3))
    found = point_normals(points, scan.ring, scan.t, 0.005, cfg)
    assert found is not None and len(built) == 1
    # and the reused normals are those of a grid built anew from a copy
    again = point_normals(points.copy(), scan.ring, scan.t, 0.005, cfg)
    assert again is not None and len(built) == 2
    np.testing.assert_array_equal(found.normals, again.normals)
    np.testing.assert_array_equal(found.has, again.has)
    np.testing.assert_array_equal(found.pixel, again.pixel)
