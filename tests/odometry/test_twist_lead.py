"""The lead of a plane-map epoch's own twist to its sweep's middle
(:func:`planodom.odometry.trend.led_twist`, :func:`planodom.odometry.trend.map_lead`)."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import OdometryConfig
from planodom.geometry import invert_transform, se3_exp, se3_log
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.trend import led_twist, map_lead

#: a body twist changing linearly in time (rad/s and m/s, and per second): a roll rate
#: swinging up and a car braking in a tightening turn
TWIST0 = np.array([0.05, -0.02, 0.3, 8.0, 0.1, 0.05])
ACCEL = np.array([0.6, 0.2, 0.4, -2.0, 0.3, -0.1])


def _pose(t: float, n: int = 4000) -> np.ndarray:
    """T_world_base at ``t`` s under the body twist TWIST0 + ACCEL t from the identity at 0:
    the product of many short steps (an independent integration, not a closed form)."""
    T = np.eye(4)
    h = t / n
    for i in range(n):
        T = T @ se3_exp((TWIST0 + ACCEL * (i + 0.5) * h) * h)
    return T


def _step_twist(a: float, b: float) -> np.ndarray:
    """The twist of the step from ``a`` to ``b`` s (what an epoch's own twist measures)."""
    return se3_log(invert_transform(_pose(a)) @ _pose(b)) / (b - a)


def test_the_lead_of_two_steps_gives_the_twist_at_the_epoch():
    """Under a twist linear in time, the constant twist of a step is the twist at its
    middle, and led along the change from the step before (of another length) it is the
    constant twist of a sweep centred on the step's end (what the epoch is deskewed
    with), where the step's own lags by half a step."""
    t0, t1, t2 = 0.40, 0.50, 0.61  # sweep middles: steps of 0.10 and 0.11 s
    previous, own = _step_twist(t0, t1), _step_twist(t1, t2)
    sweep = _step_twist(t2 - 0.05, t2 + 0.05)
    got = led_twist(own, True, t2 - t1, previous, t1 - t0)
    lag = np.abs(own - sweep)
    np.testing.assert_allclose(lag, np.abs(ACCEL) * (t2 - t1) / 2, rtol=0.2, atol=2e-3)
    # left: the steps' and the sweep's different lengths (third order in the step)
    assert np.all(np.abs(got - sweep) < 0.1 * lag + 1e-4), (got - sweep, lag)


def test_unknown_or_unmeasured_parts_are_not_led():
    own = np.array([0.1, 0.0, 0.2, 5.0, 0.0, 0.0])
    previous = np.array([0.0, 0.0, 0.1, np.nan, np.nan, np.nan])
    got = led_twist(own, True, 0.1, previous, 0.1)
    np.testing.assert_allclose(got, [0.15, 0.0, 0.25, 5.0, 0.0, 0.0])
    full = np.array([0.0, 0.0, 0.1, 4.0, 0.0, 0.0])
    np.testing.assert_allclose(led_twist(own, False, 0.1, full, 0.1)[3:], own[3:])
    np.testing.assert_allclose(led_twist(own, True, 0.1, full, 0.1)[3:], [5.5, 0.0, 0.0])
    np.testing.assert_array_equal(led_twist(own, True, 0.0, full, 0.1), own)


def _relative(status: Status) -> RelativePose:
    return RelativePose(np.eye(4), None, status)


@pytest.mark.parametrize("mode", ["rate", "twist"])
def test_map_lead_takes_the_previous_epochs_own_twist(mode: str):
    config = OdometryConfig(map_twist_lead=mode, map_lead_iterations=4)
    twist = np.arange(6.0)
    recent = [(3, twist + 1), (4, twist)]
    times = [0.0, 0.1, 0.25]
    got = map_lead(recent, 5, times, _relative(Status.OK), config)
    assert got is not None and got.previous is not None
    np.testing.assert_allclose(got.previous[:3], twist[:3])
    assert got.previous_dt == pytest.approx(0.15)
    assert got.iterations == 4
    assert got.rate_tolerance_deg_s == config.map_lead_rate_tolerance_deg_s
    if mode == "rate":
        assert np.all(np.isnan(got.previous[3:]))
    else:
        np.testing.assert_allclose(got.previous[3:], twist[3:])
    degenerate = map_lead(recent, 5, times, _relative(Status.DEGENERATE), config)
    assert degenerate is not None and degenerate.previous is not None
    assert np.all(np.isnan(degenerate.previous[3:]))
    # the previous epoch did not measure its rate: nothing led, the tolerances still hold
    for lost in (map_lead(recent, 6, times, _relative(Status.OK), config),
                 map_lead([], 5, times, _relative(Status.OK), config)):  # fmt: skip
        assert lost is not None and lost.previous is None
        own = np.ones(6)
        np.testing.assert_array_equal(lost.led(own, True, 0.1), own)
    assert map_lead(recent, 5, times, _relative(Status.OK), OdometryConfig()) is None


def test_the_lead_refines_with_its_own_tolerances():
    """An own twist 0.3 deg/s and 0.1 m/s off the one used is within the general
    tolerances (0.5 each, unchanged) but beyond the lead's (0.1 deg/s, 0.05 m/s)."""
    from planodom.odometry.twist_refine import refined_twist

    used = np.zeros(6)
    own = np.r_[np.radians([0.3, 0.0, 0.0]), 0.1, 0.0, 0.0]
    config = OdometryConfig(map_twist_lead="rate")
    np.testing.assert_array_equal(refined_twist(own, used, True, config), used)
    lead = map_lead([], 1, [0.0], None, config)
    np.testing.assert_array_equal(refined_twist(own, used, True, config, lead), own)
    np.testing.assert_array_equal(refined_twist(own, used, False, config, lead)[3:], 0.0)
