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


def _random_grid(seed: int, H: int = 16, W: int = 64) -> np.ndarray:
    """(H, W, 3) random points 1-60 m away, a tenth of the pixels empty (NaN)."""
    rng = np.random.default_rng(seed)
    P = rng.normal(size=(H, W, 3)) * rng.uniform(1.0, 60.0, size=(H, W, 1))
    P[rng.random((H, W)) < 0.1] = np.nan
    return P


def test_row_errors_rays_and_stencil_ratios_match_numpy_bit_for_bit():
    """The compiled parts of :func:`pixel_normals`' decisions equal the whole-grid numpy
    expressions (rolled grids, norms) to the bit, so the decisions are the same."""
    from planodom.extraction.lidar.normals import (
        _chord_widths,
        _row_errors,
        _stencil_ratios,
        row_chords,
        unit_rays,
    )

    for seed, K, S in ((0, 3, 2), (1, 1, 1), (2, 5, 3)):
        P, view, sigma = _random_grid(seed), np.array([0.3, -0.2, 0.8]), 0.006
        th = sum(k * (np.roll(P, -k, axis=1) - np.roll(P, k, axis=1)) for k in range(1, K + 1))
        with np.errstate(invalid="ignore", divide="ignore"):
            s2 = 2.0 * sum(k * k for k in range(1, K + 1))
            e_row = sigma * np.sqrt(s2 / np.sum(th * th, axis=2))
            ray = (P - view) / np.linalg.norm(P - view, axis=2, keepdims=True)
        width = np.linalg.norm(np.roll(ray, -K, axis=1) - np.roll(ray, K, axis=1), axis=2)
        tall = np.full(width.shape, np.nan)
        tall[S:-S] = np.linalg.norm(ray[2 * S :] - ray[: -2 * S], axis=2)
        both = np.isfinite(tall) & np.isfinite(width)
        ratio = tall[both] / np.maximum(width[both], 1e-12)

        got_e = _row_errors(P, K, sigma)
        got_ray = unit_rays(P, view)
        got_width = _chord_widths(got_ray, K)
        chord = np.linalg.norm(ray[1:] - ray[:-1], axis=2)
        assert np.array_equal(row_chords(got_ray), chord[np.isfinite(chord)])
        assert unit_rays(P, view) is got_ray
        assert np.array_equal(got_e, e_row[np.isfinite(e_row)])
        assert np.array_equal(got_ray, ray, equal_nan=True)
        assert np.array_equal(got_width, width, equal_nan=True)
        assert np.array_equal(_stencil_ratios(got_ray, S, got_width), ratio)


def _reference_pixel_normals(P, sigma, tol, cfg, view):
    """:func:`pixel_normals` ("ransac") written with ``np.median`` for every test."""
    from planodom.extraction.lidar.normals import (
        _chord_widths,
        _pixel_normals,
        _row_errors,
        _stencil_ratios,
        unit_rays,
    )

    K, ks = cfg.region_window, cfg.region_normal_sigmas
    limit = np.radians(cfg.region_max_normal_error_deg)
    e_row = _row_errors(P, K, sigma)
    if len(e_row) and np.median(e_row) > limit:
        return None
    ray = unit_rays(P, view)
    width = _chord_widths(ray, K)
    for S in range(1, P.shape[0] // 4 + 1):
        ratio = _stencil_ratios(ray, S, width)
        if S > 1 and not (len(ratio) and np.median(ratio) <= 1.0):
            return None
        n, e, ok = _pixel_normals(P, K, S, sigma, tol, ks)
        if np.count_nonzero(ok) < cfg.min_plane_points or np.median(e[ok]) <= limit:
            return S, n, e, ok
    return None


def test_pixel_normals_row_step_and_verdict_equal_the_np_median_rule():
    """The medians compared by counting (:func:`planodom.median.median_at_most`) pick the
    same row step, or decline, as ``np.median`` would, with the same arrays: a 64-beam
    scan from 2 mm (row step 1) through 6 and 12 mm (a taller step, or none) to 3 cm."""
    view = np.array([0.0, 0.0, 0.8])
    seen = set()
    for sigma in (0.002, 0.006, 0.012, 0.03):
        P = _ground_and_walls(sigma)[0]
        cfg = ExtractionConfig(range_noise_m=sigma, estimate_noise=False)
        want = _reference_pixel_normals(P, sigma, 3 * sigma, cfg, view)
        got = pixel_normals(P, sigma, 3 * sigma, cfg, view)
        assert (got is None) == (want is None), sigma
        if got is not None:
            assert all(a.tobytes() == b.tobytes() for a, b in zip(got, want[1:], strict=True))
        seen.add(None if want is None else want[0])
    assert None in seen and 1 in seen  # both verdicts were exercised
