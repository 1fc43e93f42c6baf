"""odometry.motion_model: the predicted twist of a wheeled vehicle (odometry.motion_model)."""

from collections import deque

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import twist_step
from planodom.odometry.motion_model import predicted_motion
from planodom.odometry.trend import predicted_twist


def test_constant_velocity_is_the_twist_itself():
    twist = np.array([0.01, -0.02, 0.3, 4.0, 0.7, -0.1])
    assert predicted_motion(twist, "constant_velocity") is twist


def test_nonholonomic_drops_the_lateral_velocity_only():
    twist = np.array([0.01, -0.02, 0.3, 4.0, 0.7, -0.1])
    got = predicted_motion(twist, "nonholonomic")
    np.testing.assert_array_equal(got, [0.01, -0.02, 0.3, 4.0, 0.0, -0.1])
    assert twist[4] == 0.7  # the input is not changed


def test_nonholonomic_step_follows_the_arc_of_a_car():
    """A car at v = 5 m/s turning at w = 0.5 rad/s (true lateral velocity zero) moves, over
    dt, along the circle of radius v / w: x = R sin(w dt), y = R (1 - cos(w dt))."""
    v, w, dt = 5.0, 0.5, 0.2
    step = twist_step(predicted_motion(np.array([0.0, 0.0, w, v, 0.9, 0.0]), "nonholonomic"), dt)
    R = v / w
    np.testing.assert_allclose(step[:3, 3], [R * np.sin(w * dt), R * (1 - np.cos(w * dt)), 0.0],
                               atol=1e-12)  # fmt: skip


def test_predicted_twist_pairwise_drops_lateral_velocity_map_not():
    vel: deque[np.ndarray] = deque(maxlen=5)
    twist = np.array([0.0, 0.0, 0.1, 3.0, 1.5, 0.2])
    got = predicted_twist(twist, True, deque(), vel, False, "mean", "nonholonomic")
    np.testing.assert_array_equal(got, [0.0, 0.0, 0.1, 3.0, 0.0, 0.2])
    got = predicted_twist(twist, True, deque(), deque(maxlen=5), True, "mean", "nonholonomic")
    np.testing.assert_array_equal(got, twist)  # the plane map has its own motion model


def test_unknown_model_is_refused():
    with pytest.raises(ValueError):
        predicted_motion(np.zeros(6), "bicycle")
    with pytest.raises(ConfigError):
        PlanodomConfig().updated({"odometry.motion_model": "bicycle"}, source="test")


def test_nonholonomic_degenerate_only_after_a_step_that_was_not_ok():
    """After an "ok" step the constant-velocity prediction; after one that was not, the
    same median velocity (of the measured steps) without its lateral component."""
    vel: deque[np.ndarray] = deque(maxlen=5)
    ok = np.array([0.0, 0.0, 0.1, 3.0, 0.4, 0.1])
    got = predicted_twist(ok, True, deque(), vel, False, "mean", "nonholonomic_degenerate")
    np.testing.assert_array_equal(got, ok)
    degenerate = np.array([0.0, 0.0, 0.2, 2.0, 1.5, 0.3])  # its velocity is not appended
    got = predicted_twist(degenerate, False, deque(), vel, False, "mean",
                          "nonholonomic_degenerate")  # fmt: skip
    np.testing.assert_array_equal(got, [0.0, 0.0, 0.2, 3.0, 0.0, 0.1])
