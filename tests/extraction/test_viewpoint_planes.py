"""``extraction.viewpoint_planes``: fits as flat about a plane through their viewpoint as
about their own are the lasers' cones, not surfaces (planes/builder.py)."""

from __future__ import annotations

import numpy as np

from planodom.config import PlanodomConfig
from planodom.extraction.epoch import Epoch
from planodom.extraction.lidar.path import member_fits
from planodom.extraction.planes.builder import build_planes
from planodom.scan import Scan

NOISE = 0.02


def _rays(rng, az0_deg, width_deg, elev_deg, count):
    phi = np.radians(az0_deg + rng.uniform(0, width_deg, count))
    el = np.radians(elev_deg)
    u = np.stack([np.cos(el) * np.cos(phi), np.cos(el) * np.sin(phi),
                  np.full(count, np.sin(el))], axis=1)  # fmt: skip
    return phi, u


def _along_rays(rng, u, s):
    """Points at ranges ``s`` along unit rays ``u``, range noise along the rays."""
    return (s + NOISE * rng.standard_normal(len(s)))[:, None] * u


def _scene(rng):
    """Point sets (sensor at the origin) and their scan lines: one near-level line across
    two facades at 20 and 35 m; ground 1.8 m below, five rings; a facade at 20 m, five
    near-level rings."""
    sets, rows = [], []
    phi, u = _rays(rng, 0, 28, 0.5, 80)
    half = phi >= np.radians(14)
    az = np.where(half, np.radians(21), np.radians(7))
    dist = np.where(half, 35.0, 20.0)
    s = dist / (np.cos(az) * u[:, 0] + np.sin(az) * u[:, 1])
    sets.append(_along_rays(rng, u, s))
    rows.append(np.zeros(80, dtype=np.int64))
    ground, wall = [], []
    for e in (-14, -16, -18, -20, -22):
        _, u = _rays(rng, 90, 60, e, 60)
        ground.append(_along_rays(rng, u, -1.8 / u[:, 2]))
    for e in (-2, -1, 0, 1, 2):
        _, u = _rays(rng, 170, 20, e, 60)
        wall.append(_along_rays(rng, u, -20.0 / u[:, 0]))
    for pts in (ground, wall):
        sets.append(np.vstack(pts))
        rows.append(np.repeat(np.arange(5), 60))
    return sets, rows


def _planes(mode):
    sets, rows = _scene(np.random.default_rng(4))
    points = np.vstack(sets)
    ring = np.concatenate([r + 10 * k for k, r in enumerate(rows)])
    bounds = np.cumsum([0] + [len(s) for s in sets])
    candidates = [np.arange(a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    fits = member_fits(candidates, points, ring)
    epoch = Epoch(Scan(points, ring=ring.astype(np.int32)), points, np.zeros((1, 3)), None)
    config = PlanodomConfig().updated({"extraction.viewpoint_planes": mode}).extraction
    planes, _, rejected = build_planes(fits, epoch, NOISE, config)
    return planes, rejected


def test_a_scan_line_across_facades_is_rejected_the_ground_and_a_wall_kept():
    planes, rejected = _planes("rejected")
    assert rejected == 1 and len(planes) == 2
    normals = np.array([p.normal for p in planes])
    # The ground (normal up, 1.8 m below) and the wall (normal along +x, 20 m away).
    np.testing.assert_allclose(np.abs(normals[0]), [0, 0, 1], atol=0.01)
    np.testing.assert_allclose(np.abs(normals[1]), [1, 0, 0], atol=0.01)
    np.testing.assert_allclose([planes[0].offset, planes[1].offset], [1.8, 20.0], atol=0.05)


def test_kept_by_default_the_line_fits_a_level_plane_through_the_sensor():
    planes, rejected = _planes("kept")
    assert rejected == 0 and len(planes) == 3
    line = planes[0]
    # Its "plane" is the laser's cone: nearly level, passing within cm of the sensor.
    assert abs(line.normal[2]) > 0.99 and abs(line.offset) < 0.5


def test_ransac_mode_rejects_only_the_ransac_loops_fits():
    """``viewpoint_planes: ransac`` is "rejected" for the RANSAC loop's candidates and
    "kept" for the range image's (an unorganised cloud's image, KITTI's path, untouched),
    and the builder then keeps what that rule keeps."""
    from planodom.config import ExtractionConfig
    from planodom.extraction.lidar.path import _fit_config

    cfg = ExtractionConfig(viewpoint_planes="ransac")
    assert _fit_config(cfg, ransac=True).viewpoint_planes == "rejected"
    assert _fit_config(cfg, ransac=False).viewpoint_planes == "kept"
    assert (
        _fit_config(ExtractionConfig(viewpoint_planes="kept"), ransac=True).viewpoint_planes
        == "kept"
    )
