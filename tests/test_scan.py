"""Scan: the arrays a scan holds never change after construction, and hold what was given."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.errors import GeometryError
from planodom.scan import Scan


def test_scan_owns_its_arrays_when_a_buffer_is_refilled() -> None:
    # A driver that refills one buffer per message must not change the scans built before.
    points = np.zeros((4, 3))
    ring = np.array([0, 0, 1, 1], np.int32)
    t = np.array([0.0, 0.01, 0.02, 0.03])
    first = Scan(points, ring=ring, t=t)
    points[:] = 7.0
    ring[:] = 5
    t[:] = 9.0
    assert np.all(first.points == 0.0) and list(first.ring) == [0, 0, 1, 1]
    np.testing.assert_array_equal(first.t, [0.0, 0.01, 0.02, 0.03])
    with pytest.raises(ValueError, match="read-only"):
        first.ring[0] = 3
    # Another scan's (read-only) fields are shared, not copied.
    second = Scan(first.points + 1.0, ring=first.ring, t=first.t)
    assert second.ring is first.ring and second.t is first.t


def test_extraction_sees_a_refilled_buffer_anew() -> None:
    # The extraction memoises by array identity: a scan built from a refilled buffer is
    # checked again (here: a NaN written into the buffer after the first scan).
    from planodom.errors import GeometryError
    from planodom.extraction import extract_planes

    rng = np.random.default_rng(0)
    buf = rng.uniform(-5.0, 5.0, size=(200, 3))
    extract_planes(Scan(buf))
    buf[3, 0] = np.nan
    with pytest.raises(GeometryError, match="NaN"):
        extract_planes(Scan(buf))


@pytest.mark.parametrize(
    ("ring", "problem"),
    [
        (np.array([0.0, 0.7, 2.0]), r"1 values are not int32 integers \(first: 0.7 at point 1\)"),
        (
            np.array([0.0, np.nan, 2.0]),
            r"1 values are not int32 integers \(first: nan at point 1\)",
        ),
        (np.array([0, 2**32, 1], dtype=np.int64), r"ids 0..4294967296 are beyond int32"),
        (["a", "b", "c"], "expected integer ids, got list"),
    ],
)
def test_ring_ids_a_cast_would_change_are_refused(ring, problem) -> None:
    """A ring of 0.7 was truncated to ring 0, 2**32 wrapped to 0: silently another beam."""
    with pytest.raises(GeometryError, match=rf"^scan field 'ring': {problem}$"):
        Scan(np.zeros((3, 3)), ring=ring)


def test_whole_ids_of_any_type_are_kept() -> None:
    expected = np.array([0, 5, 15], dtype=np.int32)
    for ring in (expected.astype(np.float32), expected.astype(np.uint16), [0, 5, 15]):
        got = Scan(np.zeros((3, 3)), ring=ring, label=[-1, 0, 7]).ring
        assert got.dtype == np.int32 and np.array_equal(got, expected)


def test_points_that_are_no_numbers_are_refused() -> None:
    with pytest.raises(GeometryError, match=r"^scan points: expected \(N, 3\) numbers, got str$"):
        Scan("abc")
    with pytest.raises(GeometryError, match=r"^scan field 't': expected numbers, got list$"):
        Scan(np.zeros((2, 3)), t=["a", "b"])


def test_an_array_where_a_scan_or_planes_belong_is_refused_by_the_public_api() -> None:
    """An (N, 3) array handed to the stages as an epoch ended in an AttributeError deep
    inside them ('ndarray' object has no attribute 'ring' / 'normal')."""
    import planodom

    points = np.random.default_rng(0).normal(size=(100, 3))
    with pytest.raises(GeometryError, match=r"^expected a planodom.Scan, got ndarray; "):
        planodom.extract_planes(points)
    with pytest.raises(GeometryError, match=r"^expected a planodom.Scan, got ndarray; "):
        planodom.PlaneOdometry().register_epoch(points)
    with pytest.raises(GeometryError, match=r"^expected planodom.Plane objects, got ndarray; "):
        planodom.run_odometry([points, points])
    with pytest.raises(GeometryError, match=r"^expected planodom.Plane objects, got ndarray; "):
        planodom.estimate_relative_pose(points, points)


def test_points_beyond_any_sensor_range_are_counted() -> None:
    from planodom.scan import MAX_RANGE_M, points_beyond_range

    points = np.array([[0.0, 0.0, 0.0], [600.0, 800.0, 0.0], [600.0, 800.0, 1.0], [5e5, 0, 0]])
    assert MAX_RANGE_M == 1000.0
    assert points_beyond_range(Scan(points)) == 2  # |(600, 800, 0)| = 1000 exactly is within
    assert points_beyond_range(Scan(points), max_range_m=2e6) == 0
    assert points_beyond_range(Scan(np.zeros((0, 3)))) == 0
