"""Pixel normals of a range image too noisy to grow regions on
(planodom.extraction.lidar.normals, ``region_noisy_pixels``)."""

from __future__ import annotations

import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction.lidar.grid import fill_grid, grid_indices
from planodom.extraction.lidar.normals import pixel_normals

from .synth_scans import rect, scan_lidar


def _ground_and_walls(sigma: float):
    """(H, W, 3) grid of a 64-beam scan at ``sigma`` of the ground and six walls 25-35 m
    away, its labels (H, W) (-1: no point) and the scene."""
    scene = [rect([0, 0, 0], [0, 0, 1], up=[1, 0, 0], half_u=80, half_v=80)]
    for k in range(6):
        yaw, dist = np.radians(60.0 * k + 10.0), 25.0 + 5.0 * (k % 3)
        out = np.array([np.cos(yaw), np.sin(yaw), 0.0])
        scene.append(rect(dist * out + [0, 0, 5.0], -out, half_u=9.0, half_v=5.0))
    scan = scan_lidar(scene, sigma=sigma, seed=4, n_beams=64, n_azimuth=1024, height=0.8)
    row, col, H, W = grid_indices(scan.ring, scan.t)
    P = fill_grid(scan.points, row * W + col, H * W).reshape(H, W, 3)
    label = np.full(H * W, -1)
    label[(row * W + col)[::-1]] = scan.label[::-1]  # the first point of each pixel
    return P, label.reshape(H, W), scene


def test_masked_keeps_only_pixels_within_the_limit_and_their_normals_are_true():
    """At 3 cm the median predicted error is over the limit at every row step: "ransac"
    declines the image; "masked" returns only pixels whose own predicted error is within
    it, and each of their normals is within a few predicted errors of its true surface's."""
    sigma = 0.03
    P, label, scene = _ground_and_walls(sigma)
    view = np.array([0.0, 0.0, 0.8])
    cfg = ExtractionConfig(range_noise_m=sigma, estimate_noise=False)
    assert pixel_normals(P, sigma, 3 * sigma, cfg, view) is None
    masked = cfg.model_copy(update={"region_noisy_pixels": "masked"})
    found = pixel_normals(P, sigma, 3 * sigma, masked, view)
    assert found is not None
    n, e, ok = found
    limit = np.radians(cfg.region_max_normal_error_deg)
    assert np.count_nonzero(ok) >= cfg.min_plane_points
    assert np.all(e[ok] <= limit) and np.all(np.isinf(e[~ok]))
    truth = np.array([s.normal for s in scene])[label[ok]]
    angle = np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", n[ok], truth)), 0.0, 1.0))
    assert np.median(angle / e[ok]) < 1.5
