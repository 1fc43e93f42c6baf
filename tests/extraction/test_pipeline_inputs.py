"""Degenerate and malformed input: no planes, a GeometryError or a config that does not
load, never a crash."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import ExtractionConfig
from planodom.errors import ConfigValueError, GeometryError
from planodom.extraction import extract, extract_planes
from planodom.scan import Scan

from .synth_scans import default_scene, scan_rig


@pytest.mark.parametrize("n", [0, 1, 2])
def test_too_few_points(n):
    pts = np.arange(3 * n, dtype=float).reshape(n, 3)
    assert extract_planes(Scan(pts)) == []
    assert extract_planes(Scan(pts, ring=np.zeros(n), t=np.zeros(n))) == []


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_points_raise(bad):
    pts = np.random.default_rng(0).uniform(0, 5, (50, 3))
    pts[7, 1] = bad
    with pytest.raises(GeometryError, match="NaN or infinite"):
        extract_planes(Scan(pts))


def test_non_finite_times_raise():
    scan = scan_rig(default_scene())
    t = scan.t.copy()
    t[3] = np.nan
    with pytest.raises(GeometryError, match="times"):
        extract_planes(Scan(scan.points, scan.ring, t))


def test_huge_coordinates_raise():
    pts = np.random.default_rng(0).uniform(0, 5, (50, 3))
    pts[0, 0] = 1e200
    with pytest.raises(GeometryError, match="beyond"):
        extract_planes(Scan(pts))


@pytest.mark.parametrize("ring", [None, "rig"])
def test_collinear_and_repeated_points_give_no_planes(ring):
    line = np.linspace(0, 1, 400)[:, None] * np.array([[3.0, 1.0, 0.5]]) + [1, 2, 0]
    same = np.tile([[1.0, 2.0, 3.0]], (100, 1))
    for pts in (line, same):
        r = None if ring is None else np.repeat(np.arange(2), len(pts) // 2)
        assert extract_planes(Scan(pts, ring=r)) == []


def test_one_scan_line_in_lidar_mode_gives_no_plane():
    line = np.linspace(0, 1, 400)[:, None] * np.array([[3.0, 1.0, 0.0]]) + [1, 2, 0]
    assert extract_planes(Scan(line), ExtractionConfig(mode="lidar")) == []


@pytest.mark.parametrize("twist", [np.zeros(5), np.full(6, np.nan), "fast"])
def test_bad_twist_raises(twist):
    with pytest.raises(GeometryError, match="twist"):
        extract_planes(scan_rig(default_scene()), twist=twist)


@pytest.mark.parametrize(
    "origins", [np.zeros(2), np.full(3, np.inf), np.array([[0.0, 0, 0], [1.0, 0, 0]])]
)
def test_bad_sensor_origins_raise(origins):
    with pytest.raises(GeometryError, match="sensor_origins"):
        extract_planes(scan_rig(default_scene()), sensor_origins=origins)


def test_one_origin_per_ring_of_one_sensor_needs_no_ring():
    """A lidar's rig states one origin per ring, all the same: a scan without the ring
    field is extracted as with the single origin (it raised before)."""
    scan = scan_rig(default_scene())
    lidar_like = Scan(scan.points, t=scan.t, label=scan.label)
    one = extract_planes(lidar_like, sensor_origins=np.array([0.0, 0.0, 1.0]))
    per_ring = extract_planes(lidar_like, sensor_origins=np.tile([0.0, 0.0, 1.0], (32, 1)))
    assert len(per_ring) == len(one) > 0
    assert all(np.allclose(a.normal, b.normal) for a, b in zip(one, per_ring, strict=True))


def test_bad_mode():
    # one line naming the section and field; still a ValueError, as pydantic's error was
    with pytest.raises(ConfigValueError, match=r"^ExtractionConfig: field 'mode': .*'magic'$"):
        ExtractionConfig(mode="magic")
    with pytest.raises(ValueError, match="mode"):
        ExtractionConfig(mode="magic")
    with pytest.raises(GeometryError, match="ring"):
        extract(Scan(np.zeros((10, 3))), ExtractionConfig(mode="rig2d"))
