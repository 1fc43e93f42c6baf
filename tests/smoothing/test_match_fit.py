"""The residual of a match at its own pose (planodom.smoothing.match_fit)."""

from __future__ import annotations

import numpy as np

from planodom.geometry import Plane, invert_transform, transform_from_rpy_xyz
from planodom.smoothing.match_fit import misfit


def _walls() -> list[Plane]:
    """A room's walls and its floor, in the old frame (normals towards the sensor)."""
    normals = [[1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]]
    offsets = [3.0, 2.0, 4.0, 1.5]
    return [Plane(np.array(n), d) for n, d in zip(normals, offsets, strict=True)]


def _seen_from(T_old_curr: np.ndarray, planes: list[Plane]) -> list[Plane]:
    return [p.transformed(invert_transform(T_old_curr)) for p in planes]


def test_planes_seen_from_the_matched_pose_fit_exactly():
    T = transform_from_rpy_xyz(0.0, 0.0, 0.4, 1.2, -0.7, 0.1)
    old = _walls()
    curr = _seen_from(T, old)
    pairs = np.array([[0, 0], [1, 1], [2, 2], [3, 3]])
    assert misfit(old, curr, pairs, T) < 1e-9
    flipped = [p.flipped() for p in curr]  # orientation does not matter
    assert misfit(old, flipped, pairs, T) < 1e-9


def test_a_wall_tied_to_a_parallel_wall_leaves_their_distance():
    """The current plane of wall 0 is tied to a wall parallel to it 4.9 m further: the
    residual is 4.9 m (the other pairs fit)."""
    T = transform_from_rpy_xyz(0.0, 0.0, -0.3, 0.5, 2.0, 0.0)
    old = _walls()
    curr = _seen_from(T, old)
    old.append(Plane(np.array([1.0, 0, 0]), 3.0 + 4.9))
    pairs = np.array([[4, 0], [1, 1], [2, 2], [3, 3]])
    assert abs(misfit(old, curr, pairs, T) - 4.9) < 1e-9
    assert misfit(old, curr, np.zeros((0, 2), int), T) == 0.0
