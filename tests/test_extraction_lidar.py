"""The 3D path (open3d RANSAC loop): exact planes, determinism, coplanar but separate walls."""

from __future__ import annotations

import numpy as np
from synth_scans import default_scene, planes_in_base, rect, scan_lidar

from planodom.config import ExtractionConfig
from planodom.extraction import extract

SCENE = default_scene()
TRUTH = planes_in_base(SCENE)


def test_lidar_planes_exact_and_deterministic():
    scan = scan_lidar(SCENE, n_azimuth=512)
    res = extract(scan)
    assert res.mode == "lidar"
    assert {p.truth_id for p in res.planes} == set(TRUTH)
    for p in res.planes:
        n, d = TRUTH[p.truth_id]
        assert np.degrees(np.arccos(np.clip(p.normal @ n, -1, 1))) < 1e-6
        assert abs(p.offset - d) < 1e-6
    again = extract(scan)
    assert [len(i) for i in again.inliers] == [len(i) for i in res.inliers]
    for a, b in zip(res.planes, again.planes, strict=True):
        np.testing.assert_array_equal(a.coefficients, b.coefficients)


def test_without_rings_is_3d_and_noisy_fit_is_close():
    sigma = 0.02
    scan = scan_lidar(SCENE, sigma=sigma, n_azimuth=512, with_ring=False)
    res = extract(scan, ExtractionConfig(range_noise_m=sigma))
    assert res.mode == "lidar"
    big = [p for p in res.planes if p.support.n_points > 1000]
    assert {p.truth_id for p in big} == set(TRUTH)
    for p in big:
        n, d = TRUTH[p.truth_id]
        assert np.linalg.norm(np.cross(p.normal, n)) < 5 * np.sqrt(np.trace(p.covariance[:3, :3]))
        assert abs(p.offset - d) < 5 * np.sqrt(p.covariance[3, 3]) + 1e-3


def test_coplanar_separate_walls_are_two_planes():
    scene = [
        SCENE[0],
        rect([8, -6, 2], [-1, 0, 0], half_u=3),  # two pieces of the plane x = 8,
        rect([8, 6, 2], [-1, 0, 0], half_u=3),  # 6 m apart
    ]
    res = extract(scan_lidar(scene, n_azimuth=512))
    walls = [p for p in res.planes if p.truth_id in (1, 2)]
    assert sorted(p.truth_id for p in walls) == [1, 2]
    for p in walls:
        assert p.normal[0] < -0.999 and abs(p.offset - 8.0) < 1e-6


def test_range_image_matches_truth_with_noise_and_dropouts():
    """Ringed scans take the range-image path: noisy walls within a sigma-derived bound,
    the same walls as the RANSAC path, also with no-return beams dropped."""
    sigma = 0.006
    scan = scan_lidar(SCENE, sigma=sigma, n_azimuth=1024, seed=3)
    keep = np.random.default_rng(0).random(len(scan)) > 0.05  # 5 % no-returns
    scan = scan.subset(keep)
    cfg = ExtractionConfig(range_noise_m=sigma)
    res = extract(scan, cfg)
    assert res.mode == "lidar"
    big = [p for p in res.planes if p.support.n_points > 500]
    assert {p.truth_id for p in big} == set(TRUTH)
    for p in big:
        n, d = TRUTH[p.truth_id]
        assert np.linalg.norm(np.cross(p.normal, n)) < 5 * np.sqrt(np.trace(p.covariance[:3, :3]))
        assert abs(p.offset - d) < 5 * np.sqrt(p.covariance[3, 3]) + 1e-3
    ransac = extract(scan, cfg.model_copy(update={"range_image": False}))
    assert {p.truth_id for p in ransac.planes if p.support.n_points > 500} == set(TRUTH)
