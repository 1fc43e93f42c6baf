"""Segments to planes in one compiled call (:mod:`planodom.extraction.rig2d.groups`)."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import ExtractionConfig
from planodom.extraction import deskew_points
from planodom.extraction.noise import member_tolerance, rms_limit
from planodom.extraction.rig2d.grouping import GroupingParams, _grow_kernel
from planodom.extraction.rig2d.groups import group_segments
from planodom.extraction.rig2d.segments import split_scan_lines
from planodom.extraction.rig2d.traces import build_traces

from .synth_scans import default_scene, scan_rig

XI = np.array([0.05, -0.04, 0.6, 3.0, 0.4, 0.1])


def _groups_step_by_step(segs, params, parallel_deg, step_m, seg_times):
    """The groups by :func:`.traces.build_traces`, the grouping kernel and numpy's stable
    argsort by group, called one by one from Python."""
    tr = build_traces(
        segs, params.tol_m, params.sigma_m, parallel_deg, step_m, seg_times, params.max_span_s
    )
    seg_group, n_groups, rejected = _grow_kernel(tr, params)
    group_of_seg = seg_group[tr.label]
    order = np.argsort(group_of_seg, kind="stable")
    bounds = np.searchsorted(group_of_seg[order], np.arange(n_groups + 1))
    return [order[bounds[g] : bounds[g + 1]] for g in range(n_groups)], int(rejected)


@pytest.mark.parametrize("windowed", [False, True])
@pytest.mark.parametrize("sigma", [0.002, 0.02])
def test_groups_in_one_kernel_are_the_kernels_in_sequence(windowed, sigma):
    """The same groups (segment indices, in order) and rejected seeds as the traces and
    the grouping called one by one; deskewed, and in time windows (raw points, segments'
    times, a finite time span)."""
    scan = scan_rig(default_scene(), twist=XI, sigma=sigma, seed=4)
    cfg = ExtractionConfig(range_noise_m=max(sigma, 0.002))
    pts = scan.points if windowed else deskew_points(scan.points, scan.t, XI)
    segs, sig = split_scan_lines(pts, scan.ring, scan.t, cfg)
    seg_times = None
    span = np.inf
    if windowed:
        t_sorted = scan.t[segs.order]
        seg_times = (t_sorted[segs.starts], t_sorted[segs.ends - 1])
        span = 0.5 / 75.0
    params = GroupingParams(  # as the 2D-rig path sets them from the config
        tol_m=member_tolerance(cfg, sig), sigma_m=float(sig),
        sin_min_cross=float(np.sin(np.radians(cfg.min_cross_angle_deg))),
        max_seed_err_rad=float(np.radians(cfg.max_seed_direction_error_deg)),
        min_points=float(cfg.min_plane_points), max_rms_m=rms_limit(cfg, sig),
        min_trace_points=cfg.min_segment_points, seed_floor_m=cfg.tolerance_floor_m,
        gap_m=cfg.plane_gap_m, gap_ratio=cfg.gap_range_ratio, max_span_s=span,
        max_seed_normal_err_rad=float(np.radians(cfg.max_seed_normal_error_deg)),
        min_sweep_lines=0 if windowed else 3,
        parallel_rad=float(np.radians(cfg.trace_parallel_deg)),
    )  # fmt: skip
    args = (segs, params, cfg.trace_parallel_deg, cfg.trace_step_m, seg_times)
    groups, rejected = group_segments(*args)
    ref, ref_rejected = _groups_step_by_step(*args)
    assert rejected == ref_rejected and len(groups) == len(ref) >= 3
    for g, r in zip(groups, ref, strict=True):
        assert g.dtype == r.dtype and g.tolist() == r.tolist()


def test_fewer_than_two_segments_make_no_group():
    scan = scan_rig(default_scene(), sigma=0.0)
    segs, sig = split_scan_lines(scan.points[:3], scan.ring[:3], scan.t[:3], ExtractionConfig())
    params = GroupingParams(
        tol_m=0.02, sigma_m=float(sig), sin_min_cross=0.2, max_seed_err_rad=0.05,
        min_points=30.0, max_rms_m=0.01, min_trace_points=5, seed_floor_m=0.02, gap_m=1.0,
        gap_ratio=0.2, max_span_s=np.inf, max_seed_normal_err_rad=0.1,
    )  # fmt: skip
    assert len(segs) < 2
    assert group_segments(segs, params, 2.0, 0.1) == ([], 0)
