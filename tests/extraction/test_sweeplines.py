"""Planes of walls seen by one scanner only (planodom.extraction.rig2d.sweeplines), on
hand-built scans whose true planes are known."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import ExtractionConfig
from planodom.extraction import extract
from planodom.scan import Scan

SWEEP_S = 0.05  # a 20 Hz scanner
U = np.array([0.0, np.cos(np.radians(35.0)), np.sin(np.radians(35.0))])  # line on x = const


def _wall_lines(x: float, n_sweeps: int, step_m: float, rng, sigma: float = 0.003):
    """One scanner's lines on the wall ``x = x`` in ``n_sweeps`` sweeps: 25 points over 6 m
    along ``U`` each, displaced by ``step_m`` across ``U`` in the wall per sweep (the
    motion between sweeps), noise ``sigma`` along the normal; points (M, 3), times (M,)."""
    w = np.cross([1.0, 0.0, 0.0], U)
    pts, times = [], []
    for j in range(n_sweeps):
        s = np.linspace(-3.0, 3.0, 25)
        p = np.array([x, 2.0, 1.0]) + s[:, None] * U + j * step_m * w
        p[:, 0] += rng.normal(0.0, sigma, len(s))
        pts.append(p)
        times.append(j * SWEEP_S + np.linspace(0.0, 0.004, len(s)))
    return pts, times


def _scan(walls: list[float], n_sweeps: int, step_m: float = 0.4) -> Scan:
    """One ring (scanner 0); in each sweep it crosses every wall of ``walls`` (x
    positions) once, in scan order."""
    rng = np.random.default_rng(3)
    per_wall = [_wall_lines(x, n_sweeps, step_m, rng) for x in walls]
    pts, times = [], []
    for j in range(n_sweeps):
        for k, (p, t) in enumerate(per_wall):
            pts.append(p[j])
            times.append(t[j] + 0.01 * k)  # the walls one after the other in the sweep
    points = np.concatenate(pts)
    return Scan(points, ring=np.zeros(len(points), np.int32), t=np.concatenate(times))


def _planes(scan: Scan, min_sweeps: int):
    cfg = ExtractionConfig(range_noise_m=0.003, single_scanner_min_sweeps=min_sweeps)
    return extract(scan, cfg, twist=np.zeros(6)).planes


def test_one_scanners_wall_in_four_sweeps_is_its_plane():
    """Off: no plane (no second scanner crosses the wall); on: the wall, to the noise."""
    scan = _scan([10.0], 4)
    assert _planes(scan, 0) == []
    (plane,) = _planes(scan, 3)
    assert abs(plane.normal[0]) > np.cos(np.radians(0.5))
    assert plane.offset * -np.sign(plane.normal[0]) == pytest.approx(10.0, abs=0.01)


def test_two_sweeps_never_make_a_plane():
    """Two parallel lines are always coplanar: at least three distinct lines needed."""
    assert _planes(_scan([10.0], 2), 3) == []
    assert _planes(_scan([10.0], 3), 4) == []


def test_parallel_walls_of_a_corridor_give_two_planes_not_one_across():
    """The scan plane cuts the two walls of a corridor in parallel lines: only the walls
    are planes, each from its own three sweeps (none across the corridor)."""
    planes = _planes(_scan([10.0, -4.0], 3), 3)
    assert len(planes) == 2
    xs = sorted(-p.offset / p.normal[0] for p in planes)
    assert xs == pytest.approx([-4.0, 10.0], abs=0.01)
    for p in planes:
        assert abs(p.normal[0]) > np.cos(np.radians(0.5))


def test_lines_that_do_not_move_across_each_other_are_one_line():
    """No motion across the lines (step 0): the sweeps repeat one line, no plane."""
    assert _planes(_scan([10.0], 4, step_m=0.0), 3) == []
