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


def test_unobserved_vertical_zero_keeps_a_held_vertical_velocity_out():
    """``odometry.unobserved_vertical: zero``: steps that kept the prior's z add a vertical
    velocity of zero to the window, so a wrong held one (-21 m/s, lap 366's) is gone from
    the median once the window holds more such steps than measured ones; rate and
    horizontal velocity are the steps' own."""
    held = np.array([0.0, 0.0, 0.05, 1.2, 0.01, -21.0])
    vel: deque[np.ndarray] = deque(maxlen=5)
    got = [predicted_twist(held, True, deque(), vel, False, "mean", "constant_velocity", "zero")
           for _ in range(3)]  # fmt: skip
    np.testing.assert_array_equal(got[-1], [0.0, 0.0, 0.05, 1.2, 0.01, 0.0])
    vel_held: deque[np.ndarray] = deque(maxlen=5)
    for _ in range(3):  # "held" (the default) carries it on
        out = predicted_twist(held, True, deque(), vel_held, False)
    assert out[5] == -21.0
    # a step that observed z keeps its own; median of (0, 0, 0, 0.3, 0.3) is 0
    seen = np.array([0.0, 0.0, 0.05, 1.2, 0.01, 0.3])
    for _ in range(2):
        out = predicted_twist(seen, True, deque(), vel, False, "mean", "constant_velocity")
    assert out[5] == 0.0
    out = predicted_twist(seen, True, deque(), vel, False, "mean", "constant_velocity")
    assert out[5] == 0.3  # median of (0, 0, 0.3, 0.3, 0.3)


def test_unobserved_vertical_measured_counts_the_window_median():
    """``measured``: an unobserved step counts as the median of the measured ones in the
    window (so the window's median is theirs), zero when the window is empty (after an
    unresolved epoch cleared it): a bridged -21 m/s never enters."""
    bridged = np.array([0.0, 0.0, 0.05, 1.2, 0.01, -21.0])
    vel: deque[np.ndarray] = deque(maxlen=5)
    out = predicted_twist(bridged, True, deque(), vel, False, "mean", "constant_velocity",
                          "measured")  # fmt: skip
    assert out[5] == 0.0 and out[3] == 1.2
    for vz in (0.2, 0.4):  # two steps that observed z
        predicted_twist(np.r_[bridged[:5], vz], True, deque(), vel, False)
    out = predicted_twist(bridged, True, deque(), vel, False, "mean", "constant_velocity",
                          "measured")  # fmt: skip
    # window (0, 0.2, 0.4) -> the unobserved step counts as its median 0.2; then
    # (0, 0.2, 0.4, 0.2) -> 0.2
    assert out[5] == 0.2
    assert [v[2] for v in vel] == [0.0, 0.2, 0.4, 0.2]


def test_vertical_prediction_follows_the_option_and_the_step():
    from planodom.odometry.motion_model import vertical_prediction

    base = PlanodomConfig()
    zero = base.updated({"odometry.unobserved_vertical": "zero"}, source="test")

    class Step:  # what vertical_prediction reads of a RelativePose
        def __init__(self, z_observed: bool) -> None:
            self.z_observed = z_observed

    assert vertical_prediction(base, Step(False))[2] == "held"  # type: ignore[arg-type]
    assert vertical_prediction(zero, Step(False))[2] == "zero"  # type: ignore[arg-type]
    assert vertical_prediction(zero, Step(True))[2] == "held"  # type: ignore[arg-type]
    with pytest.raises(ConfigError):
        base.updated({"odometry.unobserved_vertical": "kept"}, source="test")
