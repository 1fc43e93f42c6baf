"""The 2D rig's groups of one plane joined across the gap rule
(planodom.extraction.rig2d.coplanargroups, ``extraction.merge_coplanar_groups``)."""

from __future__ import annotations

import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction import extract
from planodom.scan import Scan

SIGMA = 0.003


def _pair(centre_x: float, height: float, rings: tuple[int, int], rng, n: int = 60):
    """Two scanners' lines of ``n`` points on the level plane z = ``height``, crossing at
    60 deg near x = ``centre_x``: points (2n, 3), rings (2n,)."""
    s = np.linspace(-4.0, 4.0, n)
    a = np.column_stack([centre_x + s, np.zeros_like(s), np.full_like(s, height)])
    u = np.array([np.cos(np.radians(60.0)), np.sin(np.radians(60.0)), 0.0])
    b = np.array([centre_x, 0.0, height]) + s[:, None] * u
    pts = np.concatenate([a, b])
    pts[:, 2] += rng.normal(0.0, SIGMA, len(pts))
    return pts, np.repeat(np.array(rings, np.int32), n)


def _two_pieces(apart_m: float, step_m: float = 0.0) -> Scan:
    """A level ground seen by rings 0, 1 near x = 3 and by rings 2, 3 near x = 3 -
    ``apart_m``, the second piece ``step_m`` higher (0: one plane, z = 0)."""
    rng = np.random.default_rng(2)
    p0, r0 = _pair(3.0, 0.0, (0, 1), rng)
    p1, r1 = _pair(3.0 - apart_m, step_m, (2, 3), rng)
    t = np.tile(np.linspace(0.0, 0.004, 60), 4)
    return Scan(np.concatenate([p0, p1]), ring=np.concatenate([r0, r1]), t=t)


def _planes(scan: Scan, on: bool):
    cfg = ExtractionConfig(range_noise_m=SIGMA, merge_coplanar_groups=on)
    return extract(scan, cfg, twist=np.zeros(6)).planes


def test_a_ground_cut_by_the_gap_rule_is_one_plane():
    """Pieces 20 m apart (beyond ``plane_gap_m``): two planes without the option, one with
    it, holding all 240 points, at the truth (z = 0) to the noise's limit."""
    scan = _two_pieces(20.0)
    assert len(_planes(scan, False)) == 2
    (plane,) = _planes(scan, True)
    assert plane.support.n_points == 240
    # the true plane: normal +-z, offset 0; a 240-point fit over 28 m at 3 mm
    assert abs(abs(plane.normal[2]) - 1.0) < 1e-6
    assert abs(plane.offset) < 3 * SIGMA / np.sqrt(240)


def test_parallel_pieces_apart_stay_two():
    """The second piece 10 cm higher (beyond the member tolerance, a kerb's step): still
    two planes, each at its own height."""
    planes = _planes(_two_pieces(20.0, step_m=0.10), True)
    assert len(planes) == 2
    heights = sorted(abs(p.offset) for p in planes)
    assert heights[0] < 0.005 and abs(heights[1] - 0.10) < 0.005


def test_pieces_within_the_gap_are_one_plane_either_way():
    """4 m apart the grouping itself joins them: the option changes nothing."""
    scan = _two_pieces(4.0)
    off, on = _planes(scan, False), _planes(scan, True)
    assert len(off) == len(on) == 1
    assert np.allclose(off[0].normal, on[0].normal) and off[0].offset == on[0].offset
