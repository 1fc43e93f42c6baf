"""Narrow seeds taken last (:mod:`planodom.extraction.rig2d.grouping`,
``extraction.narrow_seed_last_deg``), against the true planes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from pydantic import ValidationError

from planodom.config import ExtractionConfig
from planodom.errors import ConfigError
from planodom.extraction import extract
from planodom.oracle import deskewed_points
from planodom.scan import Scan
from planodom.simulation.random_world import random_world
from planodom.simulation.rigs import rig_from_name
from planodom.simulation.simulate import simulate

SIGMA = 0.006
N_LINE = 400


def _line(start, direction, length: float, ring: int, rng) -> tuple[np.ndarray, np.ndarray]:
    """``N_LINE`` points (N, 3) of one ring's scan line from ``start`` along the unit
    ``direction`` over ``length`` m, with Gaussian noise of ``SIGMA`` on every axis."""
    s = np.linspace(0.0, length, N_LINE)
    pts = np.asarray(start, float) + s[:, None] * np.asarray(direction, float)
    return pts + rng.normal(0.0, SIGMA, pts.shape), np.full(N_LINE, ring, np.int32)


def _corridor_turn(cross_deg: float) -> Scan:
    """A wall y = 3 m (normal -y towards the sensor at the origin) seen by rings 0 and 1
    as two 20 m lines crossing at ``cross_deg`` (a scanner pair on a wall at 45 deg to
    the heading), and a floor z = -1 m seen by rings 2 and 3 crossing at 60 deg."""
    rng = np.random.default_rng(7)
    half = np.radians(cross_deg / 2.0)
    rise, length = 10 * np.tan(half), 20 / np.cos(half)
    parts = [
        _line([2.0, 3.0, 0.5 - rise], [np.cos(half), 0, np.sin(half)], length, 0, rng),
        _line([2.0, 3.0, 0.5 + rise], [np.cos(half), 0, -np.sin(half)], length, 1, rng),
        _line([1.0, -1.5, -1.0], [1.0, 0.0, 0.0], 6.0, 2, rng),
        _line([2.0, -2.0, -1.0], [np.cos(np.pi / 3), np.sin(np.pi / 3), 0.0], 5.0, 3, rng),
    ]  # fmt: skip
    pts = np.concatenate([p for p, _ in parts])
    ring = np.concatenate([r for _, r in parts])
    label = np.repeat(np.array([1, 1, 0, 0], np.int32), N_LINE)
    t = np.tile(np.linspace(0.0, 0.01, N_LINE), 4)
    return Scan(pts, ring=ring, t=t, label=label)


TRUE_NORMALS = {0: np.array([0.0, 0.0, 1.0]), 1: np.array([0.0, -1.0, 0.0])}
TRUE_OFFSETS = {0: 1.0, 1: 3.0}


def _planes(scan: Scan, **fields):
    return extract(scan, ExtractionConfig(range_noise_m=SIGMA, **fields), np.zeros(6)).planes


def test_a_wall_of_two_narrow_lines_is_found_last_and_true():
    """Lines crossing at 5 deg: no wall by default, a wall with the option, at its true
    normal and offset; the floor, found by a wide seed, is the default's bit for bit."""
    scan = _corridor_turn(5.0)
    default = _planes(scan)
    assert [p.truth_id for p in default] == [0]
    last = _planes(scan, narrow_seed_last_deg=0.5)
    assert sorted(p.truth_id for p in last) == [0, 1]
    floor = next(p for p in last if p.truth_id == 0)
    assert np.array_equal(floor.normal, default[0].normal) and floor.offset == default[0].offset
    wall = next(p for p in last if p.truth_id == 1)
    # 800 points over 20 m lines 1.7 m apart at the far end: the normal to ~0.03 deg
    angle = np.degrees(np.arccos(min(1.0, abs(wall.normal @ TRUE_NORMALS[1]))))
    assert angle < 0.2
    assert abs(abs(wall.offset) - TRUE_OFFSETS[1]) < 0.01
    assert wall.support.n_points >= 2 * N_LINE - 4  # a line end may fall outside a segment


def test_narrow_seeds_under_2_deg_or_over_the_bar_seed_nothing():
    """1.5 deg (under the floor of every narrow seed) and a bar under the pair's predicted
    normal error both leave the wall out: the planes are the default's."""
    for cross, bar in ((1.5, 0.5), (5.0, 0.01)):
        scan = _corridor_turn(cross)
        got = _planes(scan, narrow_seed_last_deg=bar)
        assert [p.truth_id for p in got] == [p.truth_id for p in _planes(scan)] == [0]


def test_wide_crossings_do_not_change():
    """Lines crossing at 30 deg seed the wall by default: the option changes nothing."""
    scan = _corridor_turn(30.0)
    a, b = _planes(scan), _planes(scan, narrow_seed_last_deg=0.5)
    assert sorted(p.truth_id for p in a) == [0, 1]
    assert [(p.truth_id, p.offset, *p.normal) for p in a] == [
        (p.truth_id, p.offset, *p.normal) for p in b
    ]


def test_the_built_in_indoor_turn_keeps_its_walls():
    """The built-in random-indoor's epoch 494 (the world of seed 0, the isoclinal rig, 10
    Hz: its corridor turn at 2 cm) simulated alone and deskewed with the true motion:
    by default none of the four corridor walls the scanner pairs cross at 4-9 deg (true
    surfaces 21, 22, 23, 26) is a plane; with the option all four are, each within 0.1
    deg of its true normal (labels and the scene's surfaces, for measuring only)."""
    world = random_world(0, "indoor")
    rig = rig_from_name("isoclinal")
    t_k = 49.4
    sim = simulate(world.scene, world.trajectory, rig, n_epochs=1, epoch_rate=10.0,
                   noise_sigma=0.02, seed=3, start_time=t_k)  # fmt: skip
    scan = sim.scans[0]
    exact = dataclasses.replace(scan, points=deskewed_points(scan, world.trajectory, t_k))
    R_world_base = world.trajectory.pose(t_k)[:3, :3]
    walls = {21, 22, 23, 26}

    def planes(**fields):
        cfg = ExtractionConfig(**fields)
        return extract(exact, cfg, np.zeros(6), rig.sensor_origins).planes

    assert not walls & {p.truth_id for p in planes()}
    got = {p.truth_id: p for p in planes(narrow_seed_last_deg=0.5)}
    assert walls <= set(got)
    for i in walls:
        n_true = world.scene.by_id(i).normal @ R_world_base
        assert np.degrees(np.arccos(min(1.0, abs(got[i].normal @ n_true)))) < 0.1


@pytest.mark.parametrize("bad", [-0.1, 91.0, float("nan")])
def test_a_bad_bar_is_refused_at_load(bad):
    with pytest.raises((ConfigError, ValidationError), match="narrow_seed_last_deg"):
        ExtractionConfig(narrow_seed_last_deg=bad)


def test_the_narrow_wall_is_marked_and_the_wide_planes_are_not():
    """``Plane.narrow`` (:mod:`planodom.extraction.rig2d.narrow`): the wall of two lines
    crossing at 5 deg is narrow, the floor (60 deg) is not; at 30 deg neither is, and
    without the option no plane is marked."""
    got = {p.truth_id: p.narrow for p in _planes(_corridor_turn(5.0), narrow_seed_last_deg=0.5)}
    assert got == {0: False, 1: True}
    wide = _planes(_corridor_turn(30.0), narrow_seed_last_deg=0.5)
    assert sorted(p.truth_id for p in wide) == [0, 1] and not any(p.narrow for p in wide)
    assert not any(p.narrow for p in _planes(_corridor_turn(30.0)))
