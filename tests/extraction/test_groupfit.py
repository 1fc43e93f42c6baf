"""The group refits as the builder's input in one compiled call
(:func:`planodom.extraction.rig2d.groupfit.plane_fits`)."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import ExtractionConfig
from planodom.extraction import deskew_points
from planodom.extraction.noise import member_tolerance, rms_limit
from planodom.extraction.planes.builder import PlaneFits
from planodom.extraction.rig2d.groupfit import fit_groups, plane_fits
from planodom.extraction.rig2d.grouping import GroupingParams
from planodom.extraction.rig2d.groups import group_segments
from planodom.extraction.rig2d.segments import split_scan_lines

from .synth_scans import default_scene, scan_rig

XI = np.array([0.05, -0.04, 0.6, 3.0, 0.4, 0.1])


def _plane_fits_step_by_step(segs, groups, k_sigma, viewpoint):
    """:func:`.groupfit.fit_groups`, then numpy from Python: reversed eigen views, the
    offsets by einsum, the inliers through ``segs.order``."""
    fits = fit_groups(segs, groups, k_sigma, viewpoint)
    evecs = fits.evecs[:, :, ::-1]
    return PlaneFits(
        count=fits.count,
        centroid=fits.centroid,
        offset=-np.einsum("gi,gi->g", evecs[:, :, 2], fits.centroid),
        evals=fits.evals[:, ::-1],
        evecs=evecs,
        inliers=segs.order[fits.inliers],
        bounds=fits.bounds,
        outline=fits.is_end,
        incidence=None if viewpoint is None else fits.incidence,
    )


def _assert_same_bits(a: PlaneFits, b: PlaneFits) -> None:
    for name in ("count", "centroid", "offset", "evals", "evecs", "inliers", "bounds",
                 "outline", "incidence", "n_rows"):  # fmt: skip
        x, y = getattr(a, name), getattr(b, name)
        if y is None:
            assert x is None, name
            continue
        assert x.dtype == y.dtype and x.shape == y.shape, name
        assert x.size == 0 or x.strides == y.strides, name  # numpy's empty results vary
        assert x.tobytes() == y.tobytes(), name


def _segments_and_groups(sigma, windowed):
    """A deskewed (or raw, in time windows) 2D-rig scan's segments and groups, with the
    grouping parameters the 2D-rig path sets from the default config."""
    scan = scan_rig(default_scene(), twist=XI, sigma=sigma, seed=4)
    cfg = ExtractionConfig(range_noise_m=max(sigma, 0.002))
    pts = scan.points if windowed else deskew_points(scan.points, scan.t, XI)
    segs, sig = split_scan_lines(pts, scan.ring, scan.t, cfg)
    seg_times = None
    if windowed:
        t_sorted = scan.t[segs.order]
        seg_times = (t_sorted[segs.starts], t_sorted[segs.ends - 1])
    params = GroupingParams(
        tol_m=member_tolerance(cfg, sig), sigma_m=float(sig),
        sin_min_cross=float(np.sin(np.radians(cfg.min_cross_angle_deg))),
        max_seed_err_rad=float(np.radians(cfg.max_seed_direction_error_deg)),
        min_points=float(cfg.min_plane_points), max_rms_m=rms_limit(cfg, sig),
        min_trace_points=cfg.min_segment_points, seed_floor_m=cfg.tolerance_floor_m,
        gap_m=cfg.plane_gap_m, gap_ratio=cfg.gap_range_ratio,
        max_span_s=0.5 / 75.0 if windowed else np.inf,
        max_seed_normal_err_rad=float(np.radians(cfg.max_seed_normal_error_deg)),
        min_sweep_lines=0 if windowed else 3,
        parallel_rad=float(np.radians(cfg.trace_parallel_deg)),
    )  # fmt: skip
    groups, _ = group_segments(segs, params, cfg.trace_parallel_deg, cfg.trace_step_m, seg_times)
    return segs, groups, cfg


@pytest.mark.parametrize("windowed", [False, True])
@pytest.mark.parametrize("sigma", [0.0, 0.002, 0.02])
def test_plane_fits_in_one_kernel_are_the_old_sequence(windowed, sigma):
    """The same arrays, bit for bit and in the same memory layout, as the refit followed
    by numpy: with and without a viewpoint, for all groups, a subset in another order
    (the path drops groups), and none."""
    segs, groups, cfg = _segments_and_groups(sigma, windowed)
    assert len(groups) >= 3
    view = np.array([0.0, 0.0, cfg.viewpoint_height_m])
    subset = [groups[k] for k in range(len(groups) - 1, -1, -2)]
    for gs in (groups, subset, []):
        for viewpoint in (None, view):
            new = plane_fits(segs, gs, cfg.inlier_sigma_factor, viewpoint)
            old = _plane_fits_step_by_step(segs, gs, cfg.inlier_sigma_factor, viewpoint)
            assert len(new) == len(gs)
            _assert_same_bits(new, old)


def test_offsets_are_the_normals_through_the_centroids():
    """Against an independent computation: each plane passes through its centroid with
    the normal its third eigenvector column, and holds its inliers (scan indices)."""
    segs, groups, cfg = _segments_and_groups(0.0, False)
    fits = plane_fits(segs, groups, cfg.inlier_sigma_factor, None)
    scan_points = np.empty_like(segs.points)
    scan_points[segs.order] = segs.points
    for g in range(len(fits)):
        n = fits.evecs[g][:, 2]
        assert abs(n @ fits.centroid[g] + fits.offset[g]) < 1e-12
        assert np.abs(scan_points[fits.members(g)] @ n + fits.offset[g]).max() < 1e-6
