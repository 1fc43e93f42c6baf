"""Trajectories: rigid, exactly evaluable, constant speed, yaw along the path, small sway."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.linalg import expm

from planodom.errors import GeometryError
from planodom.geometry import (
    invert_transform,
    rpy_from_rotation,
    se3_exp,
    transform_from_rpy_xyz,
)
from planodom.simulation import (
    PAPER_LOOP_ROUTE,
    StaticTrajectory,
    Sway,
    TwistTrajectory,
    WaypointTrajectory,
    paper_loop_trajectory,
    urban_canyon_trajectory,
)
from planodom.simulation.trajectory import _rotations

angle = st.floats(-3.0, 3.0)


@given(angle, st.floats(-1.5, 1.5), angle)
def test_rotations_match_geometry(roll, pitch, yaw):
    cs = [f(np.array([a])) for a in (roll, pitch, yaw) for f in (np.cos, np.sin)]
    R = _rotations(*cs)[0]
    np.testing.assert_allclose(
        R, transform_from_rpy_xyz(roll, pitch, yaw, 0, 0)[:3, :3], atol=1e-14
    )


def _assert_rigid(T: np.ndarray) -> None:
    R = T[:, :3, :3]
    np.testing.assert_allclose(
        R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12
    )
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    np.testing.assert_array_equal(T[:, 3], np.broadcast_to([0, 0, 0, 1.0], (len(T), 4)))


@pytest.fixture(scope="module")
def loop():
    return paper_loop_trajectory()


def test_loop_is_rigid_and_vectorised(loop):
    t = np.linspace(-5.0, 2 * loop.duration, 997)
    T = loop.poses(t)
    assert T.shape == (997, 4, 4)
    _assert_rigid(T)
    for i in (0, 100, 996):
        np.testing.assert_array_equal(loop.pose(t[i]), T[i])


def test_loop_speed_heading_and_closure(loop):
    assert 100 < loop.length < 250 and loop.duration == pytest.approx(loop.length / 2.0)
    t = np.linspace(0.0, loop.duration, 20001)
    T = loop.poses(t)
    v = np.diff(T[:, :2, 3], axis=0) / np.diff(t)[:, None]
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 2.0, rtol=1e-4)
    # yaw along the path: the base x axis (projected) points along the velocity
    heading = T[:-1, :2, 0] / np.linalg.norm(T[:-1, :2, 0], axis=1, keepdims=True)
    cos = np.sum(heading * v / np.linalg.norm(v, axis=1, keepdims=True), axis=1)
    assert cos.min() > np.cos(np.deg2rad(0.5))
    # closed loop: continuous across the lap (positions, yaw)
    a, b = loop.poses(np.array([loop.duration - 1e-6, loop.duration + 1e-6]))
    assert np.linalg.norm(a[:3, 3] - b[:3, 3]) < 1e-4
    # passes through every waypoint
    d = np.linalg.norm(T[:, None, :2, 3] - PAPER_LOOP_ROUTE[None], axis=2).min(axis=0)
    assert d.max() < 0.01


def test_loop_sway_exercises_all_rotation_rates(loop):
    t = np.linspace(0.0, 30.0, 3001)
    T = loop.poses(t)
    rpy = np.array([rpy_from_rotation(R) for R in T[:, :3, :3]])
    assert 0.5 < np.rad2deg(np.abs(rpy[:, 0]).max()) <= 2.0  # roll
    assert 0.5 < np.rad2deg(np.abs(rpy[:, 1]).max()) <= 2.0  # pitch
    z = T[:, 2, 3]
    assert np.abs(z - 1.0).max() <= 0.05 and np.ptp(z) > 0.01
    # relative rotations over 0.1 s have all three components
    rel = np.array([invert_transform(T[i]) @ T[i + 10] for i in range(0, 3000, 10)])
    rates = np.array([rpy_from_rotation(R[:3, :3]) for R in rel]) / 0.1
    assert np.all(np.abs(rates).max(axis=0) > 0.01)


def test_still_sway_is_flat():
    tr = WaypointTrajectory(PAPER_LOOP_ROUTE, sway=Sway.still(), height=2.0)
    T = tr.poses(np.linspace(0, 10, 50))
    np.testing.assert_allclose(T[:, 2, 3], 2.0)
    np.testing.assert_allclose(T[:, 2, :3], np.broadcast_to([0, 0, 1.0], (50, 3)), atol=1e-15)


def test_open_path_holds_its_ends():
    tr = urban_canyon_trajectory(speed=5.0)
    assert tr.duration == pytest.approx(tr.length / 5.0)
    T = tr.poses(np.array([-3.0, 0.0, tr.duration, tr.duration + 3.0]))
    np.testing.assert_allclose(T[0, :2, 3], T[1, :2, 3])
    np.testing.assert_allclose(T[2, :2, 3], T[3, :2, 3])
    np.testing.assert_allclose(T[2, :2, 3], [150.0, 0.0], atol=1e-9)


def test_bad_waypoints():
    with pytest.raises(GeometryError):
        WaypointTrajectory(np.zeros((2, 2)), closed=True)
    with pytest.raises(GeometryError):
        WaypointTrajectory(PAPER_LOOP_ROUTE, speed=0.0)


twist = st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6)


@given(twist, st.floats(-2.0, 2.0))
def test_se3_exp_matches_matrix_exponential(xi, t):
    xi = np.array(xi)
    X = np.zeros((4, 4))
    w = xi[:3]
    X[:3, :3] = [[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]
    X[:3, 3] = xi[3:]
    np.testing.assert_allclose(se3_exp((t * xi)[None])[0], expm(t * X), atol=1e-12)


@given(twist, st.floats(0.0, 1.0), st.floats(0.0, 1.0))
def test_twist_trajectory_is_a_one_parameter_group(xi, a, b):
    T0 = transform_from_rpy_xyz(0.1, -0.2, 0.3, 1.0, 2.0, 3.0)
    tr = TwistTrajectory(T0, xi)
    Ta, Tab = tr.poses(np.array([a, a + b]))
    np.testing.assert_allclose(Tab, Ta @ se3_exp((b * np.array(xi))[None])[0], atol=1e-12)
    np.testing.assert_allclose(tr.pose(0.0), T0, atol=1e-15)


def test_static_trajectory():
    T = transform_from_rpy_xyz(0, 0, 1.0, 3, 4, 1)
    np.testing.assert_array_equal(StaticTrajectory(T).poses(np.zeros(3)), np.stack([T] * 3))


def test_se3_exp_is_accurate_for_tiny_rotations() -> None:
    """Against scipy's rotation and the series of the left Jacobian, across the switch."""
    from scipy.spatial.transform import Rotation

    for th in (1e-9, 1e-6, 5e-4, 2e-3, 0.3):
        w = th * np.array([0.6, -0.8, 0.0])
        v = np.array([1.0, 2.0, -0.5])
        T = se3_exp(np.concatenate([w, v])[None])[0]
        np.testing.assert_allclose(T[:3, :3], Rotation.from_rotvec(w).as_matrix(), atol=1e-15)
        # J_l(w) v by its power series sum_k [w]^k v / (k+1)!, independent of the closed form.
        K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        term, series, fact = v.copy(), v.copy(), 1.0
        for k in range(1, 25):
            term = K @ term
            fact *= k + 1
            series = series + term / fact
        np.testing.assert_allclose(T[:3, 3], series, atol=1e-14)
