"""The residual of a match at its own pose (planodom.smoothing.match_fit)."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from planodom.geometry import Plane, invert_transform, transform_from_rpy_xyz
from planodom.smoothing.match_fit import offset_residuals, offset_statistic


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
    r, normals, var = offset_residuals(old, curr, pairs, T, 0.02)
    assert np.abs(r).max() < 1e-9
    np.testing.assert_allclose(normals, [p.normal for p in old])
    np.testing.assert_allclose(var, 2 * 0.02**2)  # no covariances: the default, twice
    flipped = [p.flipped() for p in curr]  # orientation does not matter
    assert np.abs(offset_residuals(old, flipped, pairs, T, 0.02)[0]).max() < 1e-9


def test_a_wall_tied_to_a_parallel_wall_leaves_their_distance():
    """The current plane of wall 0 is tied to a wall parallel to it 4.9 m further: the
    residual is 4.9 m (the other pairs fit)."""
    T = transform_from_rpy_xyz(0.0, 0.0, -0.3, 0.5, 2.0, 0.0)
    old = _walls()
    curr = _seen_from(T, old)
    old.append(Plane(np.array([1.0, 0, 0]), 3.0 + 4.9))
    pairs = np.array([[4, 0], [1, 1], [2, 2], [3, 3]])
    r = offset_residuals(old, curr, pairs, T, 0.02)[0]
    np.testing.assert_allclose(np.abs(r), [4.9, 0, 0, 0], atol=1e-9)
    assert len(offset_residuals(old, curr, np.zeros((0, 2), int), T, 0.02)[0]) == 0


def test_the_statistic_weighs_the_residual_by_the_drift_along_the_normal():
    """Closed form: a residual r along normal n under drift covariance D and plane
    variance v is chi2(1) distributed as r^2 / (n^T D n + v); drift across the normal
    does not widen the bound."""
    normals = np.array([[1.0, 0.0, 0.0]])
    v = np.array([0.02**2])
    along = np.diag([0.5**2, 1e-6])
    across = np.diag([1e-6, 0.5**2])
    assert np.isclose(offset_statistic(np.array([1.0]), normals, v, along), 1.0 / 0.2504)
    assert offset_statistic(np.array([1.0]), normals, v, across) > chi2.ppf(0.999, 1)
    assert offset_statistic(np.zeros(0), np.zeros((0, 3)), np.zeros(0), along) == 0.0
