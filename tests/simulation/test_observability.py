"""Observability of walls as planes: traces from labels and rings, and the default rig."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.scan import Scan
from planodom.simulation import (
    Scene,
    Simulator,
    epoch_observability,
    ground,
    isoclinal_rig,
    paper_loop,
    paper_loop_trajectory,
    ring_traces,
    wall,
)

SCENE = Scene(
    (
        ground(0, [[-50, -50], [50, -50], [50, 50], [-50, 50]]),
        wall(1, (10, -5), (10, 5), 0.0, 5.0),
        wall(2, (-5, 10), (5, 10), 0.0, 5.0),
    )
)


def _line(label: int, ring: int, start, direction, n: int = 50) -> Scan:
    s = np.linspace(0.0, 3.0, n)[:, None]
    pts = np.asarray(start, float) + s * np.asarray(direction, float)
    return Scan(pts, np.full(n, ring), np.zeros(n), np.full(n, label))


def _join(*scans: Scan) -> Scan:
    return Scan(
        *(np.concatenate([getattr(s, f) for s in scans]) for f in ("points", "ring", "t", "label"))
    )


def test_crossing_traces_make_a_wall_observable():
    up, along = np.array([0, 0, 1.0]), np.array([0, 1.0, 0])
    crossing = _join(
        _line(1, 0, (10, -1, 1), along + 0.5 * up), _line(1, 1, (10, -1, 3), along - 0.5 * up)
    )
    parallel = _join(_line(1, 0, (10, -1, 1), along), _line(1, 1, (10, -1, 3), along))
    single = _line(1, 0, (10, -1, 1), along + 0.5 * up)
    assert epoch_observability(crossing, SCENE).walls_observable == (1,)
    assert epoch_observability(parallel, SCENE).walls_observable == ()
    assert epoch_observability(single, SCENE).walls_observable == ()
    assert epoch_observability(single, SCENE).walls_hit == (1,)


def test_pairs_and_ground():
    along1, along2 = np.array([0, 1.0, 0.5]), np.array([1.0, 0, 0.5])
    flip = np.array([1, 1, -1.0])
    scan = _join(
        _line(1, 0, (10, -1, 1), along1),
        _line(1, 1, (10, -1, 3), along1 * flip),
        _line(2, 2, (-1, 10, 1), along2),
        _line(2, 3, (-1, 10, 3), along2 * flip),
        _line(0, 0, (3, 0, 0), (0, 1, 0)),
        _line(0, 1, (-3, 0, 0), (0, 1, 0)),
    )
    obs = epoch_observability(scan, SCENE)
    assert obs.walls_observable == (1, 2) and obs.n_pairs == 1 and obs.ground_observable


def test_short_or_sparse_traces_are_ignored():
    scan = _join(
        _line(1, 0, (10, -1, 1), (0, 0.1, 0.05)), _line(1, 1, (10, -1, 1), (0, 1, -1), n=3)
    )
    assert len(ring_traces(scan).label) == 0


@pytest.mark.parametrize("t", [0.0, 12.0, 25.0, 37.0, 50.0, 62.0])
def test_default_rig_observes_walls_as_planes_around_the_loop(t):
    """RIG.md's check: in every epoch, >= 3 walls with two non-parallel traces and >= 1
    pair of non-parallel such walls (the rotation and translation need one)."""
    scene = paper_loop()
    sim = Simulator(scene, paper_loop_trajectory(), isoclinal_rig())
    obs = epoch_observability(sim.epoch(0, t).scan, scene)
    assert len(obs.walls_observable) >= 3
    assert obs.n_pairs >= 1
    assert obs.ground_observable
