"""Scan: the arrays a scan holds never change after construction."""

from __future__ import annotations

import numpy as np
import pytest

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
