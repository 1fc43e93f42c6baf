"""The yaw rate along its trend to a suspect epoch's points (:mod:`.odometry.turn_trend`)."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import OdometryConfig, PlanodomConfig
from planodom.errors import ConfigError
from planodom.experiments.generalisation import world_for
from planodom.extraction import extract_planes
from planodom.geometry import Plane, invert_transform, se3_log
from planodom.odometry.deskew import EpochEstimate, register_deskewed
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.turn_trend import turn_trend
from planodom.planes import PlaneSet
from planodom.simulation.simulate import simulate

DT = 0.2
ON = OdometryConfig(turn_trend_retry=True)


def _rates(w0: float, a: float, epochs: range) -> list[tuple[int, np.ndarray]]:
    """Own twists of steps into ``epochs`` under the yaw rate ``w0 + a t`` (t = k DT): the
    mean over a step is the rate at its middle, ``(j - 1/2) DT``."""
    return [(j, np.r_[0.01, -0.02, w0 + a * (j - 0.5) * DT, 5.0, 0.0, 0.0]) for j in epochs]


def test_a_steady_tightening_is_extrapolated_to_the_points_mean_time():
    w0, a, k = 0.3, 0.6, 36  # rad/s, rad/s^2: 6.9 deg/s an epoch
    times = np.array([0.0, 0.09, 0.18])  # mean 0.09 s after the epoch time
    predicted = np.r_[0.02, 0.01, w0 + a * (k - 1.5) * DT, 4.0, 0.1, 0.0]  # the last step's
    for cfg in (ON, OdometryConfig(turn_trend_retry=True, turn_trend_rates=5)):
        out = turn_trend(_rates(w0, a, range(31, 36)), k, times, DT, predicted, cfg)
        assert out is not None
        np.testing.assert_allclose(out[2], w0 + a * (k * DT + 0.09))  # the rate at the points
        np.testing.assert_array_equal(np.delete(out, 2), np.delete(predicted, 2))  # the rest
    # the last three only: a trend that changed before them is not followed
    bent = _rates(w0, -a, range(28, 33)) + _rates(w0 - 2 * a * 32.5 * DT, a, range(33, 36))
    out = turn_trend(bent, k, times, DT, predicted, ON)
    assert out is not None
    np.testing.assert_allclose(out[2], w0 - 2 * a * 32.5 * DT + a * (k * DT + 0.09))


def test_nothing_is_tried_when_off_short_stale_or_within_the_tolerance():
    times, k = np.array([0.0, 0.18]), 36
    rates = _rates(0.3, 0.6, range(31, 36))
    predicted = rates[-1][1]  # the last step's: 0.23 rad/s (13 deg/s) below the trend
    assert turn_trend(rates, k, times, DT, predicted, OdometryConfig()) is None  # off
    assert turn_trend(rates, k, times, DT, None, ON) is None  # no prediction
    assert turn_trend(rates, k, None, DT, predicted, ON) is None
    assert turn_trend(rates, k, np.array([]), DT, predicted, ON) is None
    assert turn_trend(rates, k, times, 0.0, predicted, ON) is None
    assert turn_trend(rates[2:], k, times, DT, predicted, ON) is not None  # three are enough
    assert turn_trend(rates[3:], k, times, DT, predicted, ON) is None  # two are not
    four = OdometryConfig(turn_trend_retry=True, turn_trend_rates=4)
    assert turn_trend(rates[2:], k, times, DT, predicted, four) is None
    assert turn_trend(rates[:-1], k, times, DT, predicted, ON) is None  # 35 not measured
    steady = _rates(0.3, 0.0, range(31, 36))  # a steady turn: the trend is the prediction
    assert turn_trend(steady, k, times, DT, steady[-1][1], ON) is None
    tol = OdometryConfig(turn_trend_retry=True, deskew_rate_tolerance_deg_s=60.0)
    assert turn_trend(rates, k, times, DT, predicted, tol) is None  # 13 deg/s off: within 60


def test_a_bad_value_names_its_key():
    with pytest.raises(ConfigError, match="turn_trend_retry"):
        PlanodomConfig.from_dict({"odometry": {"turn_trend_retry": "sometimes"}})


def _estimate(status: Status, n: int, twist: np.ndarray | None) -> EpochEstimate:
    """An estimate of ``status`` with ``n`` walls."""
    planes = [Plane(np.array([np.cos(a), np.sin(a), 0.0]), -5.0) for a in np.arange(n) * 0.7]
    rel = RelativePose(np.eye(4), np.zeros((5, 5)), status)
    return EpochEstimate(planes, PlaneSet.from_planes(planes), twist, rel, np.eye(4), [])


def test_the_trend_is_tried_before_none_only_for_a_suspect_epoch_and_kept_when_better():
    predicted, trend = np.r_[0.0, 0.0, 0.40, 5.0, 0, 0], np.r_[0.0, 0.0, 0.47, 5.0, 0, 0]
    for first, tried in ((Status.OK, 1), (Status.DEGENERATE, 3)):
        calls: list[np.ndarray | None] = []

        def estimate(twist, source=None, first=first, calls=calls):  # noqa: ANN001, ANN202
            calls.append(twist)
            if twist is None:
                return _estimate(Status.DEGENERATE, 2, None)
            return _estimate(Status.OK if twist[2] > 0.45 else first, 3, twist)

        cfg = OdometryConfig(deskew_iterations=0)
        best = register_deskewed(predicted, DT, estimate, lambda t: False, cfg, trend=trend)
        assert len(calls) == tried
        assert best.twist is not None and best.relative.status is Status.OK
        if tried == 3:
            assert calls[1] is trend and best.twist is trend


def _twist(world, a: float, b: float) -> np.ndarray:  # noqa: ANN001
    """(6,) the true mean twist over ``[a, b]`` s (rad/s, m/s)."""
    return se3_log(invert_transform(world.trajectory.pose(a)) @ world.trajectory.pose(b)) / (b - a)


def test_world_244s_tightening_turn_keeps_its_surfaces_with_the_trend():
    """The 2D-rig world 244 (10 Hz) tightens a left turn by about 2.5 deg/s an epoch at
    epochs 31-38, ever faster. The prediction for epoch 36, the true rate of the step into
    35, lags the twist over 36's points by 5 deg/s and keeps 2 of the 5 true surfaces the
    true twist over the points gives (sigma 0); the trend of the true steps into 33-35
    extrapolated to the points' mean time is 1.0 deg/s low (a line through a rate whose
    change grows) and keeps 4 of them, none split."""
    world, k = world_for(244), 36
    dt = 1.0 / world.epoch_rate
    sim = simulate(world.scene, world.trajectory, world.sensor_rig, n_epochs=1,
                   epoch_rate=world.epoch_rate, noise_sigma=0.0, start_time=k * dt)  # fmt: skip
    scan = sim.scans[0]
    truth = _twist(world, k * dt + float(scan.t.min()), k * dt + float(scan.t.max()))
    rates = [(j, _twist(world, (j - 1) * dt, j * dt)) for j in range(31, 36)]
    predicted = rates[-1][1]
    led = turn_trend(rates, k, scan.t, dt, predicted, ON)
    assert led is not None
    assert np.degrees(truth[2] - predicted[2]) > 4.0  # the lag
    assert abs(np.degrees(led[2] - truth[2])) < 1.1

    def surfaces(twist: np.ndarray) -> list[int]:
        planes = extract_planes(scan, PlanodomConfig().extraction, twist=twist,
                                sensor_origins=sim.rig.sensor_origins)  # fmt: skip
        return [p.truth_id for p in planes]

    exact, lagging, trended = surfaces(truth), surfaces(predicted), surfaces(led)
    assert len(exact) == len(set(exact)) >= 4
    assert len(set(lagging)) < len(lagging) or set(lagging) < set(exact)  # split or lost
    assert len(trended) == len(set(trended)) and set(trended) <= set(exact)
    assert len(trended) >= len(set(lagging)) + 2


def test_with_status_the_trend_needs_a_better_status_and_none_keeps_its_rank():
    predicted, trend = np.r_[0.0, 0.0, 0.40, 5.0, 0, 0], np.r_[0.0, 0.0, 0.47, 5.0, 0, 0]
    cfg = OdometryConfig(deskew_iterations=0)

    def run(trend_given, trend_result, none_result):  # noqa: ANN001, ANN202
        def estimate(twist, source=None):  # noqa: ANN001, ANN202
            if twist is None:
                return _estimate(*none_result, None)
            if twist is trend:
                return _estimate(*trend_result, twist)
            return _estimate(Status.DEGENERATE, 2, twist)

        return register_deskewed(predicted, DT, estimate, lambda t: False, cfg,
                                 trend=trend_given, trend_status=True)  # fmt: skip

    more_planes = run(trend, (Status.DEGENERATE, 5), (Status.UNRESOLVED, 1))
    assert more_planes.twist is predicted  # by rank it would be the trend
    better = run(trend, (Status.OK, 3), (Status.UNRESOLVED, 1))
    assert better.twist is trend
    # without a trend, the extraction without a twist is still judged by its rank
    assert run(None, (Status.OK, 3), (Status.DEGENERATE, 4)).twist is None
