"""The rate an unresolved epoch is bridged with (``odometry.bridge_rate``,
:mod:`planodom.odometry.bridge_trend`), against closed forms and a simulated turn."""

from __future__ import annotations

import numpy as np
import pytest
from planes_factory import observe, world_planes

from planodom.config import OdometryConfig, PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import invert_transform, se3_log, transform_from_rpy_xyz, twist_step
from planodom.odometry import PlaneOdometry
from planodom.odometry.bridge_trend import bridge, bridge_twist

#: a turn whose rate grows by 0.02 rad/s an epoch from 0.1, at 3 m/s forward
RATES = [(k, np.array([0.0, 0.0, 0.1 + 0.02 * k, 3.0, 0.0, 0.0])) for k in range(2, 7)]
TWIST = np.array([0.0, 0.0, 0.2, 2.9, 0.05, 0.01])  # the prediction (its rate: the last)
TREND = OdometryConfig(bridge_rate="trend")


def test_last_is_the_prediction_itself():
    """Off (the default): the prediction, the same object (outputs cannot move)."""
    assert bridge_twist(TWIST, RATES, 7, OdometryConfig()) is TWIST
    pred, T = np.eye(4), np.eye(4)
    pred[0, 3] = 0.5
    assert bridge(pred, T, TWIST, 0.2, RATES, 7, OdometryConfig()) is pred


def test_a_steady_change_is_followed_to_the_bridged_epoch():
    """Rates on a line: the bridged epoch's rate is the line's there (closed form), the
    velocity the prediction's."""
    got = bridge_twist(TWIST, RATES, 8, TREND)
    assert got is not None
    np.testing.assert_allclose(got[:3], [0.0, 0.0, 0.1 + 0.02 * 8], atol=1e-12)
    np.testing.assert_array_equal(got[3:], TWIST[3:])


def test_the_trend_runs_no_further_than_its_bound():
    """Past ``bridge_trend_epochs`` after the last measured rate, the rate stays the one
    the trend reached there."""
    for bound in (1, 3):
        cfg = OdometryConfig(bridge_rate="trend", bridge_trend_epochs=bound)
        got = bridge_twist(TWIST, RATES, 30, cfg)
        assert got is not None
        assert got[2] == pytest.approx(0.1 + 0.02 * (6 + bound), abs=1e-12)


def test_too_few_rates_or_no_prediction_keep_the_prediction():
    assert bridge_twist(TWIST, RATES[:3], 8, TREND) is TWIST
    assert bridge_twist(None, RATES, 8, TREND) is None
    T = np.eye(4)
    assert bridge(None, T, None, 0.2, RATES, 8, TREND) is T  # standing still: no motion


def test_the_bridge_is_the_trend_twists_step_from_the_last_pose():
    T = transform_from_rpy_xyz(0.01, 0.0, 0.3, 1.0, 2.0, 0.0)
    pred = T @ twist_step(TWIST, 0.2)
    got = bridge(pred, T, TWIST, 0.2, RATES, 8, TREND)
    expected = T @ twist_step(np.r_[0.0, 0.0, 0.26, TWIST[3:]], 0.2)
    np.testing.assert_allclose(got, expected, atol=1e-12)


def test_config_refuses_a_bad_value_naming_the_key():
    with pytest.raises(ConfigError, match="^config: field 'odometry.bridge_rate': "):
        PlanodomConfig.from_dict({"odometry": {"bridge_rate": "mean"}})
    with pytest.raises(ConfigError, match="^config: field 'odometry.bridge_trend_epochs': "):
        PlanodomConfig.from_dict({"odometry": {"bridge_trend_epochs": 0}})


@pytest.mark.parametrize("mode", ["last", "trend"])
def test_a_blind_epoch_in_a_tightening_turn(mode):
    """A vehicle turning ever faster (yaw rate up 0.2 rad/s each 0.1 s epoch) sees nothing
    at epoch 8: bridged with the last rate its yaw lags the truth by one epoch's change
    times dt (0.02 rad); along the trend of the measured rates it is the true step's (the rates lie
    on a line)."""
    rng = np.random.default_rng(4)
    world = world_planes(rng, 10)
    dt, n = 0.1, 10
    yaw = [sum(0.1 + 0.2 * j for j in range(1, k + 1)) * dt for k in range(n)]  # rad
    poses = [transform_from_rpy_xyz(0.0, 0.0, yaw[k], 0.3 * k, 0.0, 0.0) for k in range(n)]
    cfg = PlanodomConfig.from_dict({"odometry": {"pipeline": "wocsc", "bridge_rate": mode}})
    odo = PlaneOdometry(cfg)
    for k, T in enumerate(poses):
        odo.register_planes([] if k == 8 else observe(world, T), time=dt * k)
    assert str(odo.results[8].status) == "unresolved"
    step = invert_transform(odo.poses[7]) @ odo.poses[8]
    true = invert_transform(poses[7]) @ poses[8]
    err = se3_log(step)[2] - se3_log(true)[2]
    if mode == "trend":
        assert abs(err) < 1e-6
    else:
        assert err == pytest.approx(-0.2 * dt, abs=1e-6)  # one epoch's change lagged
