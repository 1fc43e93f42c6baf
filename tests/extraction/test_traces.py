"""Trace merging over sweeps, segment trimming, the support polygon (2D-rig path)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from planodom.config import ExtractionConfig
from planodom.extraction import deskew_points, extract_planes
from planodom.extraction.planes.fit import robust_plane_fit
from planodom.extraction.planes.support import majority_label, support_polygon
from planodom.extraction.rig2d.segments import segment_features, split_scan_lines
from planodom.extraction.rig2d.traces import build_traces

from .synth_scans import default_scene, rect, scan_rig

XI = np.array([0.05, -0.04, 0.6, 3.0, 0.4, 0.1])


@pytest.mark.parametrize("sigma", [0.0, 0.006])
def test_traces_are_one_per_ring_and_wall(sigma):
    # 7 sweeps of a moving rig: each scanner's segments on one wall become one trace.
    scan = scan_rig(default_scene(), twist=XI, sigma=sigma, seed=1)
    cfg = ExtractionConfig(range_noise_m=max(sigma, 0.002))
    pts = deskew_points(scan.points, scan.t, XI)
    segs, sig = split_scan_lines(pts, scan.ring, scan.t, cfg)
    tr = build_traces(segs, max(3 * sig, 0.02), sig, 2.0, 0.1)
    lab = np.array(
        [
            majority_label(scan.label[segs.order[a:b]])
            for a, b in zip(segs.starts, segs.ends, strict=True)
        ]
    )
    pure = [len(set(lab[tr.label == k])) == 1 for k in range(len(tr.ring))]
    assert all(pure)
    # Collinear pieces of one trace may stay apart (a gap), but not more than a few.
    assert len(tr.ring) <= len(set(zip(segs.ring, lab, strict=True))) + 2
    assert len(tr.ring) < len(segs) / 4
    assert tr.count[tr.count >= 3 * 3].sum() >= 0.99 * tr.count.sum()  # several sweeps each


@pytest.mark.parametrize("n_sweeps", [1, 7])
def test_two_beams_per_sweep_merge_into_a_trace(n_sweeps):
    # A narrow pillar 6 m ahead: each forward scanner puts only two beams on it per sweep
    # (6 deg steps). Over 7 sweeps the 2-point pieces merge into traces of 14 points and
    # the pillar is a plane; from one sweep (2 + 2 points) it is not guessed.
    scene = [
        rect([5, 0, 0], [0, 0, 1], up=[1, 0, 0], half_u=30, half_v=30),
        rect([6, 0, 2], [-1, 0, 0], half_u=0.5, half_v=2.0),
    ]
    scan = scan_rig(scene, step_deg=6.0, n_sweeps=n_sweeps)
    on_pillar = scan.label == 1
    for ring in (0, 1):  # the premise: two beams per sweep and scanner
        assert np.count_nonzero(on_pillar & (scan.ring == ring)) == 2 * n_sweeps
    planes = extract_planes(scan, twist=np.zeros(6))
    pillar = [p for p in planes if p.truth_id == 1]
    if n_sweeps == 1:
        assert pillar == []
        return
    assert len(pillar) == 1
    np.testing.assert_allclose(pillar[0].normal, [-1.0, 0.0, 0.0], atol=1e-9)
    assert abs(pillar[0].offset - 6.0) < 1e-9


def test_support_polygon_is_the_hull_up_to_sampling():
    rng = np.random.default_rng(0)
    uv = rng.uniform([-3, -1], [3, 1], (400, 2))
    pts = np.column_stack([uv, 0.5 * uv[:, 0] + 2.0])
    fit = robust_plane_fit(pts, 3.5)
    poly = support_polygon(pts, fit.centroid, fit.evecs[:, :2])
    # Every vertex is an input point, on the plane.
    assert np.all(np.min(np.linalg.norm(pts[None] - poly[:, None], axis=2), axis=1) < 1e-12)
    # Convex, and its area is within 3 % of the exact hull's.
    q = (poly - fit.centroid) @ fit.evecs[:, :2]
    e = np.roll(q, -1, axis=0) - q
    cross = e[:, 0] * np.roll(e[:, 1], -1) - e[:, 1] * np.roll(e[:, 0], -1)
    assert np.all(cross > 0) or np.all(cross < 0)
    area = 0.5 * abs(np.sum(q[:, 0] * np.roll(q[:, 1], -1) - np.roll(q[:, 0], -1) * q[:, 1]))
    hull = ConvexHull((pts - fit.centroid) @ fit.evecs[:, :2]).volume
    assert 0.97 * hull <= area <= hull + 1e-9


def test_segment_end_point_off_the_line_is_trimmed():
    # Ten points on a line, then a corner point 3 cm off it (tolerance 2 cm): the chord of
    # the split runs through it, so the segment's fit must drop it.
    u = np.array([0.6, 0.8, 0.0])
    pts = np.array([[1.0, 2.0, 0.5]]) + np.arange(10)[:, None] * 0.1 * u
    corner = pts[-1] + 0.05 * u + np.array([0.0, 0.0, 0.03])
    pts = np.vstack([pts, corner])
    zeros = np.zeros(len(pts), dtype=np.int64)
    segs = segment_features(
        pts, np.arange(len(pts)), zeros, zeros, np.array([0]), np.array([len(pts)]), 3, 0.1, 0.02
    )
    assert len(segs) == 1
    assert (segs.starts[0], segs.ends[0]) == (0, 10)
    assert abs(abs(segs.direction[0] @ u) - 1.0) < 1e-12
    assert segs.rms[0] < 1e-7  # sqrt of round-off


def test_gather_rows_is_numpys_row_indexing():
    """The compiled reorder of the points by ring (:func:`.segments.gather_rows`) against
    ``points[order]`` on random points and orders (a permutation, repeats, empty)."""
    from planodom.extraction.rig2d.segments import gather_rows

    rng = np.random.default_rng(2)
    pts = rng.normal(size=(500, 3)) * 30.0
    for order in (rng.permutation(500), rng.integers(0, 500, size=77), np.zeros(0, np.int64)):
        got = gather_rows(pts, order.astype(np.int64))
        assert got.shape == (len(order), 3) and got.tobytes() == pts[order].tobytes()


def _split_step_by_step(points, ring, t, cfg):
    """The scan lines' segments and sigma by the Python-level sequence of kernels that
    :func:`.segments._split` runs as one compiled call."""
    from planodom.extraction.noise import noise_sigma
    from planodom.extraction.rig2d.scanlines import (
        estimate_line_noise_2d,
        ring_plane_coordinates,
        run_breaks,
        split_runs,
    )
    from planodom.extraction.rig2d.segments import gather_rows, ring_order

    order, rg, tt, timing = ring_order(ring, t)
    pts = gather_rows(points, order)
    run_start, sweep_start = run_breaks(
        pts, rg, tt, cfg.sweep_gap_factor, cfg.min_gap_m, cfg.gap_range_ratio, timing
    )
    x, y = ring_plane_coordinates(pts, rg)
    estimate = estimate_line_noise_2d(x, y, run_start) if cfg.estimate_noise else 0.0
    sigma = noise_sigma(cfg.estimate_noise, cfg.range_noise_m, estimate)
    split_tol = max(cfg.split_sigma_factor * sigma, cfg.tolerance_floor_m)
    starts = np.flatnonzero(run_start)
    s, e = split_runs(x, y, starts, np.append(starts[1:], len(pts)), split_tol)
    sweep = np.cumsum(sweep_start) - 1
    segs = segment_features(pts, order, rg, sweep, s, e, 2, cfg.min_segment_length_m, split_tol)
    return segs, sigma


@pytest.mark.parametrize("times", ["timed", "untimed", "equal"])
@pytest.mark.parametrize("estimate", [True, False])
def test_split_in_one_kernel_is_the_kernels_in_sequence(times, estimate):
    """:func:`.segments.split_scan_lines` (one compiled call) gives the same segments,
    bit for bit, as its kernels called one by one from Python; with times, without (the
    scan angle's reversals cut the sweeps) and with all times equal."""
    scan = scan_rig(default_scene(), twist=XI, sigma=0.006, seed=3)
    pts = deskew_points(scan.points, scan.t, XI)
    t = {"timed": scan.t, "untimed": None, "equal": np.zeros(len(scan.t))}[times]
    cfg = ExtractionConfig(range_noise_m=0.004, estimate_noise=estimate)
    segs, sigma = split_scan_lines(pts, scan.ring, t, cfg)
    ref, ref_sigma = _split_step_by_step(pts, scan.ring, t, cfg)
    assert sigma == ref_sigma and len(segs) == len(ref) > 20
    for name, a in vars(ref).items():
        b = getattr(segs, name)
        assert b.dtype == a.dtype and b.shape == a.shape and b.tobytes() == a.tobytes(), name
