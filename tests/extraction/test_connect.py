"""The gap rule of the 2D-rig grouping (planodom.extraction.rig2d.connect)."""

from __future__ import annotations

import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction import extract
from planodom.extraction.rig2d.connect import connected_piece, segment_distance
from planodom.scan import Scan


def _lines(centres):
    """Traces along x, 4 m long, at the given centres (K, 3)."""
    c = np.asarray(centres, dtype=np.float64)
    d = np.tile([1.0, 0.0, 0.0], (len(c), 1))
    return c, d, np.full(len(c), -2.0), np.full(len(c), 2.0)


def test_segment_distance_against_dense_sampling():
    rng = np.random.default_rng(0)
    for _ in range(50):
        p0, p1, q0, q1 = rng.normal(size=(4, 3)) * 3.0
        s = np.linspace(0.0, 1.0, 401)
        a = p0 + s[:, None] * (p1 - p0)
        b = q0 + s[:, None] * (q1 - q0)
        dense = np.min(np.linalg.norm(a[:, None] - b[None], axis=2))
        assert segment_distance(p0, p1, q0, q1) <= dense + 1e-12
        assert segment_distance(p0, p1, q0, q1) >= dense - 0.05


def test_piece_of_one_seed_or_of_either_seed():
    """Traces 0 and 1 are 5 m apart, 2 lies 30 m beyond and 3 next to it: with a 10 m gap
    the piece of trace 0 is {0, 1}; of either of 0 and 2, all four."""
    c, d, lo, hi = _lines([[0, 0, 0], [0, 5, 0], [0, 35, 0], [0, 38, 0]])
    members = np.ones(4, dtype=np.bool_)
    one = connected_piece(members, 0, c, d, lo, hi, 10.0, 0.0)
    assert one.tolist() == [True, True, False, False]
    both = connected_piece(members, 0, c, d, lo, hi, 10.0, 0.0, 2)
    assert both.tolist() == [True, True, True, True]
    # a second seed that is not a member changes nothing
    members[2] = False
    again = connected_piece(members, 0, c, d, lo, hi, 10.0, 0.0, 2)
    assert again.tolist() == [True, True, False, False]


def _floor_scan(apart_m: float, n: int = 60) -> Scan:
    """Two scanners' lines of ``n`` points each on the floor z = 0, crossing at 60 deg,
    ``apart_m`` apart."""
    rng = np.random.default_rng(1)
    s = np.linspace(-4.0, 4.0, n)
    a = np.column_stack([3.0 + s, np.zeros_like(s), rng.normal(0, 0.003, len(s))])
    u = np.array([np.cos(np.radians(60.0)), np.sin(np.radians(60.0)), 0.0])
    b = np.array([-apart_m, 0.0, 0.0]) + s[:, None] * u
    b[:, 2] = rng.normal(0, 0.003, len(s))
    pts = np.concatenate([a, b])
    ring = np.repeat(np.array([0, 1], np.int32), len(s))
    t = np.tile(np.linspace(0.0, 0.004, len(s)), 2)
    return Scan(pts, ring=ring, t=t)


def test_a_floor_seen_by_two_scanners_far_apart():
    """Two crossing traces coplanar to the noise, 20 m apart (beyond ``plane_gap_m``): the
    floor only with ``seed_spans_gap``; 4 m apart, with or without."""
    for apart, expected in ((20.0, {False: 0, True: 1}), (4.0, {False: 1, True: 1})):
        for on in (False, True):
            cfg = ExtractionConfig(range_noise_m=0.003, seed_spans_gap=on)
            planes = extract(_floor_scan(apart), cfg, twist=np.zeros(6)).planes
            assert len(planes) == expected[on], (apart, on)
            for p in planes:
                assert p.normal[2] > np.cos(np.radians(0.5))
                assert abs(p.offset) < 0.01


def test_short_traces_far_apart_are_not_one_plane():
    """Two traces of 12 points (fewer than ``min_plane_points`` each) 20 m apart: no plane
    even with ``seed_spans_gap`` (two short traces of two walls far apart can be
    coplanar by chance); 4 m apart they are one."""
    for apart, expected in ((20.0, 0), (4.0, 1)):
        cfg = ExtractionConfig(range_noise_m=0.003, seed_spans_gap=True)
        planes = extract(_floor_scan(apart, n=12), cfg, twist=np.zeros(6)).planes
        assert len(planes) == expected, apart


def _tilted(scan: Scan, tilt_deg: float) -> Scan:
    """``scan`` turned about the x axis by ``tilt_deg``: its floor becomes a plane whose
    normal is ``tilt_deg`` from z (90: a wall)."""
    c, s = np.cos(np.radians(tilt_deg)), np.sin(np.radians(tilt_deg))
    R = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    return Scan(scan.points @ R.T, ring=scan.ring, t=scan.t)


def test_the_span_kept_for_level_planes_only():
    """With ``seed_spans_gap_max_tilt_deg: 30`` two crossing traces 20 m apart stay one
    plane when their plane is within 30 deg of level (0 and 20 deg), and are dropped by the
    gap rule when it is steeper (45 deg, a wall at 90); the default 90 keeps every tilt."""
    for tilt in (0.0, 20.0, 45.0, 90.0):
        scan = _tilted(_floor_scan(20.0), tilt)
        for max_tilt, expected in ((30.0, 1 if tilt < 30.0 else 0), (90.0, 1)):
            cfg = ExtractionConfig(
                range_noise_m=0.003, seed_spans_gap=True, seed_spans_gap_max_tilt_deg=max_tilt
            )
            planes = extract(scan, cfg, twist=np.zeros(6)).planes
            assert len(planes) == expected, (tilt, max_tilt)
            for p in planes:
                assert abs(abs(p.normal[2]) - np.cos(np.radians(tilt))) < 0.01
