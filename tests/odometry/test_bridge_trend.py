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


def test_median_is_numpys_median_of_the_last_n_rates():
    """``median``: each angular component the median (np.median, independent of the
    code's path) of the last N measured rates; the velocity the prediction's."""
    rng = np.random.default_rng(11)
    rates = [(k, rng.normal(size=6)) for k in range(3, 12)]
    for n in (1, 2, 5, 9, 30):
        cfg = OdometryConfig(bridge_rate="median", bridge_median_steps=n)
        got = bridge_twist(TWIST, rates, 12, cfg)
        assert got is not None
        known = np.array([tw[:3] for _, tw in rates])[-n:]
        expected = [float(np.median(known[:, i])) for i in range(3)]
        np.testing.assert_array_equal(got[:3], expected)
        np.testing.assert_array_equal(got[3:], TWIST[3:])


def test_median_waits_for_three_rates_unless_fewer_are_asked_for():
    five = OdometryConfig(bridge_rate="median", bridge_median_steps=5)
    assert bridge_twist(TWIST, RATES[:2], 8, five) is TWIST
    got = bridge_twist(TWIST, RATES[:3], 8, five)  # rates 0.14, 0.16, 0.18: median 0.16
    assert got is not None and got[2] == pytest.approx(0.16, abs=1e-12)
    one = OdometryConfig(bridge_rate="median", bridge_median_steps=1)
    got = bridge_twist(TWIST, RATES[:1], 8, one)
    assert got is not None
    np.testing.assert_array_equal(got[:3], RATES[0][1][:3])
    assert bridge_twist(None, RATES, 8, five) is None


def test_config_refuses_a_bad_median_window_naming_the_key():
    with pytest.raises(ConfigError, match="^config: field 'odometry.bridge_median_steps': "):
        PlanodomConfig.from_dict({"odometry": {"bridge_median_steps": 0}})
    with pytest.raises(ConfigError, match="^config: field 'odometry.bridge_median_steps': "):
        PlanodomConfig.from_dict({"odometry": {"bridge_median_steps": "five"}})


def _blind_turn(odometry: dict) -> tuple[PlaneOdometry, list[np.ndarray]]:
    """The tightening turn below (yaw rate 0.1 + 0.2 k rad/s at 0.1 s epochs), epoch 8
    blind; its odometry run with ``odometry`` and the true poses (4, 4)."""
    rng = np.random.default_rng(4)
    world = world_planes(rng, 10)
    dt, n = 0.1, 10
    yaw = [sum(0.1 + 0.2 * j for j in range(1, k + 1)) * dt for k in range(n)]  # rad
    poses = [transform_from_rpy_xyz(0.0, 0.0, yaw[k], 0.3 * k, 0.0, 0.0) for k in range(n)]
    cfg = PlanodomConfig.from_dict({"odometry": {"pipeline": "wocsc", **odometry}})
    odo = PlaneOdometry(cfg)
    for k, T in enumerate(poses):
        odo.register_planes([] if k == 8 else observe(world, T), time=dt * k)
    assert str(odo.results[8].status) == "unresolved"
    return odo, poses


def test_median_of_one_step_is_last_exactly_in_a_run():
    """N = 1 in a run whose prediction's rate is the last step's own: every pose equal to
    ``last``'s, bit for bit."""
    last, _ = _blind_turn({"bridge_rate": "last"})
    one, _ = _blind_turn({"bridge_rate": "median", "bridge_median_steps": 1})
    for a, b in zip(last.poses, one.poses, strict=True):
        np.testing.assert_array_equal(a, b)


def test_median_of_five_bridges_with_the_middle_rate_of_a_steady_change():
    """Rates on a line (epochs 3-7 measured 0.7-1.5 rad/s): their median is epoch 5's,
    1.1 rad/s, for a true 1.7 at epoch 8: the bridged step's yaw 0.06 rad short (closed
    form; a steadily tightening turn is where the median lags, not what it is for)."""
    odo, poses = _blind_turn({"bridge_rate": "median", "bridge_median_steps": 5})
    step = invert_transform(odo.poses[7]) @ odo.poses[8]
    true = invert_transform(poses[7]) @ poses[8]
    assert se3_log(step)[2] - se3_log(true)[2] == pytest.approx(-0.6 * 0.1, abs=1e-6)
