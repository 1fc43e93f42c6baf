"""A gap's bridge rate robust to one bad step (``odometry.bridge_rate: robust``,
:mod:`planodom.odometry.bridge_robust`), against closed forms and a simulated turn."""

from __future__ import annotations

import numpy as np
import pytest
from planes_factory import observe, world_planes

from planodom.config import OdometryConfig, PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import invert_transform, se3_log, transform_from_rpy_xyz
from planodom.odometry import PlaneOdometry
from planodom.odometry.bridge_robust import (
    rate_variance,
    robust_rate,
    robust_twist,
    walk_variance,
)
from planodom.odometry.bridge_trend import bridge_twist
from planodom.odometry.relative import RelativePose

TWIST = np.array([0.01, -0.02, 0.2, 2.9, 0.05, 0.01])  # a prediction (rad/s, m/s)
ROBUST = OdometryConfig(bridge_rate="robust")


def _window(y: list[float], sd: list[float]) -> tuple[list, list]:
    """(rates, variances) of epochs 3, 4, ...: yaw rates ``y`` (rad/s) with stated yaw
    sds ``sd`` (rad/s), roll and pitch equal to the prediction's, same sds."""
    rates = [(3 + i, np.r_[TWIST[:2], yi, TWIST[3:]]) for i, yi in enumerate(y)]
    return rates, [np.full(3, s**2) for s in sd]


def _batch_walk(x: np.ndarray, y: np.ndarray, v: np.ndarray, q: float) -> float:
    """The last rate of the least-squares random walk through the window, solved as one
    linear system (independent of the filter): minimise sum (y_i - r_i)^2 / v_i +
    sum (r_i+1 - r_i)^2 / (q (x_i+1 - x_i)); the filter's last estimate is the smoother's."""
    n = len(y)
    A, b = np.diag(1.0 / v), y / v
    for i in range(n - 1):
        w = 1.0 / (q * (x[i + 1] - x[i]))
        A[i, i] += w
        A[i + 1, i + 1] += w
        A[i, i + 1] -= w
        A[i + 1, i] -= w
    return float(np.linalg.solve(A, b)[-1])


def test_the_filter_is_the_random_walks_least_squares():
    """Random windows (gaps between steps, variances spread over two decades) against
    the batch solution with the window's walk variance."""
    rng = np.random.default_rng(7)
    for _ in range(20):
        x = np.cumsum(rng.integers(1, 3, 5)).astype(float)
        v = 10 ** rng.uniform(-4, -2, 5)
        y = 0.3 + np.cumsum(rng.normal(0, 0.1, 5)) + rng.normal(0, np.sqrt(v))
        q = walk_variance(x[:-1], y[:-1], v[:-1])
        if q == 0.0:
            continue  # a mean: the next test
        assert robust_rate(x, y, v) == pytest.approx(_batch_walk(x, y, v, q), rel=1e-9)


def test_walk_variance_of_a_ramp():
    """Rates rising by s an epoch, each stated variance v: (s^2 - 2 v) an epoch; over
    steps two epochs apart (2 s)^2 - 2 v over 2; never below 0."""
    x = np.arange(4.0)
    assert walk_variance(x, 0.05 * x, np.full(4, 1e-4)) == pytest.approx(0.05**2 - 2e-4)
    assert walk_variance(2 * x, 0.1 * x, np.full(4, 1e-4)) == pytest.approx((0.1**2 - 2e-4) / 2)
    assert walk_variance(x, 0.0 * x, np.full(4, 1e-4)) == 0.0


def test_a_chain_that_alternates_is_no_walk():
    """Rates 2, 0, +20, -21 deg/s, each stated sd 4.5 (random-outdoor at 2 cm, noise seed
    2): they differ from their neighbours far beyond their stated noise, but no more from
    their second neighbours (variogram: 382 against 695 (deg/s)^2): q = 0. The last step
    then, +24.9 deg/s at sd 4.5, is one of five in their variance-weighted mean."""
    x = np.arange(5.0)
    y = np.radians([2.0, 0.0, 20.0, -21.0, 24.9])
    v = np.radians(np.full(5, 4.5)) ** 2
    assert walk_variance(x[:-1], y[:-1], v[:-1]) == 0.0
    assert robust_rate(x, y, v) == pytest.approx(float(np.mean(y)), abs=1e-12)


def test_a_steady_turn_with_one_poor_outlier_is_pulled_to_the_others():
    """Four steps at 0.1 rad/s, each stated sd 0.01, and a last one 0.35 rad/s off with
    sd 0.05: the others do not move (q = 0), so the rate is the variance-weighted mean of
    the five (closed form), 0.1 + 0.35 / 101."""
    rates, var = _window([0.1, 0.1, 0.1, 0.1, 0.45], [0.01] * 4 + [0.05])
    got = robust_twist(np.r_[TWIST[:2], 0.45, TWIST[3:]], rates, var)
    w = np.array([1e-4] * 4 + [0.05**2]) ** -1.0
    assert got[2] == pytest.approx(float(w @ np.array([0.1] * 4 + [0.45]) / w.sum()), abs=1e-12)
    assert got[2] == pytest.approx(0.1 + 0.35 / 101, abs=1e-12)
    np.testing.assert_array_equal(got[[0, 1]], TWIST[[0, 1]])  # constant: the same value
    np.testing.assert_array_equal(got[3:], TWIST[3:])


def test_a_ramping_rate_is_kept_within_its_change():
    """A turn's onset: rates rising by 0.05 rad/s an epoch, each sd 0.002: the walk's
    variance (0.05^2 - 8e-6) dwarfs the last step's, which is kept within 0.2 % of one
    epoch's change (the filter's lag: one change times v / (q + v))."""
    rates, var = _window([0.0, 0.05, 0.1, 0.15, 0.2], [0.002] * 5)
    got = robust_twist(TWIST, rates, var)
    assert abs(got[2] - 0.2) < 0.002 * 0.05


def test_a_precise_step_at_a_turns_onset_stays_near_its_own_rate():
    """World 200's onset (BRIDGEMED): four steps near -5 deg/s that move by 0.4-1.1 deg/s
    an epoch (more than their stated 0.02-0.04), then +3.9 deg/s stated 0.06 two epochs
    later: it moves by under 1 % of its departure (0.5 %)."""
    y = np.radians([-4.3, -5.4, -5.0, -4.1, 3.9])
    rates, var = _window(list(y), list(np.radians([0.02, 0.02, 0.03, 0.04, 0.06])))
    rates[-1] = (rates[-1][0] + 1, rates[-1][1])  # epochs 3-6, then 8
    got = robust_twist(TWIST, rates, var)
    assert abs(got[2] - y[-1]) < 0.01 * abs(y[-1] - y[-2])


def test_a_constant_rate_is_kept_exactly():
    rates, var = _window([0.2] * 5, [0.01] * 5)
    got = bridge_twist(TWIST, rates, 9, ROBUST, var)
    assert got is not None
    np.testing.assert_array_equal(got, TWIST)


def test_too_few_or_unknown_keep_the_prediction():
    """Fewer than four rates, variances not given, the last's unknown, or fewer than
    three others known: the prediction itself."""
    rates, var = _window([0.1, 0.1, 0.1, 0.45], [0.01] * 3 + [0.05])
    assert robust_twist(TWIST, rates[1:], var[1:]) is TWIST
    assert bridge_twist(TWIST, rates, 9, ROBUST) is TWIST  # no variances (the map's)
    assert bridge_twist(None, rates, 9, ROBUST, var) is None
    unknown = [*var[:-1], np.full(3, np.nan)]
    assert robust_twist(TWIST, rates, unknown) is TWIST
    two_known = [np.full(3, np.nan), *var[1:]]
    assert robust_twist(TWIST, rates, two_known) is TWIST
    assert robust_twist(TWIST, rates, var) is not TWIST  # all known: filtered


def test_rate_variance_is_the_rotation_diagonal_over_dt_squared():
    cov = np.diag([1e-4, 4e-4, 9e-4, 1e-2, 1e-2])
    rel = RelativePose(T_prev_curr=np.eye(4), covariance=cov)
    np.testing.assert_allclose(rate_variance(rel, 0.1), [1e-2, 4e-2, 9e-2], rtol=1e-12)
    assert np.isnan(rate_variance(RelativePose(np.eye(4), None), 0.1)).all()
    assert np.isnan(rate_variance(rel, 0.0)).all()


def test_config_refuses_a_bad_value_naming_the_key():
    assert PlanodomConfig.from_dict({"odometry": {"bridge_rate": "robust"}})
    with pytest.raises(ConfigError, match="^config: field 'odometry.bridge_rate': "):
        PlanodomConfig.from_dict({"odometry": {"bridge_rate": "robustly"}})


def _turn(mode: str, bad_rad: float, rate: float = 0.3) -> tuple[float, PlaneOdometry]:
    """A steady turn (``rate`` rad/s, 0.1 s epochs, 3 m/s), epoch 7 seen from a pose
    ``bad_rad`` further in yaw (its step measures that much too much), epoch 8 blind:
    the bridged step 7-8's yaw error (rad) against the truth, and the run."""
    rng = np.random.default_rng(4)
    world = world_planes(rng, 10)
    dt, n = 0.1, 11
    poses = [transform_from_rpy_xyz(0.0, 0.0, rate * dt * k, 0.3 * k, 0.0, 0.0) for k in range(n)]
    cfg = PlanodomConfig.from_dict({"odometry": {"pipeline": "wocsc", "bridge_rate": mode}})
    odo = PlaneOdometry(cfg)
    for k, T in enumerate(poses):
        seen = T @ transform_from_rpy_xyz(0.0, 0.0, bad_rad, 0.0, 0.0, 0.0) if k == 7 else T
        odo.register_planes([] if k == 8 else observe(world, seen), time=dt * k)
    assert str(odo.results[8].status) == "unresolved"
    step = invert_transform(odo.poses[7]) @ odo.poses[8]
    true = invert_transform(poses[7]) @ poses[8]
    return float(se3_log(step)[2] - se3_log(true)[2]), odo


def test_a_run_bridges_one_bad_step_with_a_fifth_of_its_error():
    """Epoch 7's step measured 0.01 rad too far, its stated variance the others' (the
    same planes): ``last`` holds it, the bridged step 0.01 rad off; ``robust`` weighs it
    as one of five equally precise rates of a steady turn (four others, one Kalman
    update), 0.01 / 5 off (closed form)."""
    last, _ = _turn("last", 0.01)
    robust, _ = _turn("robust", 0.01)
    assert last == pytest.approx(0.01, abs=1e-6)
    assert robust == pytest.approx(0.01 / 5, abs=1e-6)


def test_a_run_without_an_outlier_is_last():
    """A steady turn measured exactly: the filtered rate is the rate, the run ``last``'s
    to rounding."""
    _, last = _turn("last", 0.0)
    _, robust = _turn("robust", 0.0)
    for a, b in zip(last.poses, robust.poses, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-12)
