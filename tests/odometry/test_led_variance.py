"""The led twist's variance in closed form (planodom.odometry.led_variance), against Monte
Carlo draws of the lead itself."""

import numpy as np
import pytest

from planodom.odometry.led_variance import lead_variance, velocity_variance
from planodom.odometry.relative import RelativePose, Status


def _monte_carlo(v_own, v_prev, c, k, g, n=400_000, seed=3):
    """Empirical variance of ``own + g k (own - previous)`` against the value at the lead's
    time, the rate changing linearly by ``c`` a step (the lead's own model)."""
    rng = np.random.default_rng(seed)
    true_prev = 0.1
    true_own = true_prev + c
    target = true_own + k * c
    own = true_own + rng.normal(0.0, np.sqrt(v_own), n)
    prev = true_prev + rng.normal(0.0, np.sqrt(v_prev), n)
    led = own + g * k * (own - prev)
    return float(np.mean((led - target) ** 2))


@pytest.mark.parametrize("g", [0.0, 0.3, 1.0])
@pytest.mark.parametrize(("v_own", "v_prev", "c"), [(4e-6, 1e-6, 0.0), (1e-6, 9e-6, 5e-3)])
def test_the_closed_form_is_the_leads_error_variance(v_own, v_prev, c, g):
    k = 0.5
    # the closed form takes the measured change, whose square exceeds the true one's by
    # v_own + v_prev in expectation; given that expectation it must give the true variance
    change = np.array([np.sqrt(c**2 + v_own + v_prev)])
    got = lead_variance(np.array([v_own]), np.array([v_prev]), change, k, np.array([g]))[0]
    want = _monte_carlo(v_own, v_prev, c, k, g)
    assert got == pytest.approx(want, rel=0.01)


def test_a_change_within_its_noise_leaves_no_unled_term():
    v = np.array([1e-6, 1e-6, 1e-6])
    small = np.array([1e-4, 0.0, -1e-3])  # squares below v_own + v_prev = 2e-6
    got = lead_variance(v, v, small, 0.5, np.zeros(3))
    np.testing.assert_allclose(got, v)  # not led: the own rate's noise only


def test_velocity_variance_from_the_steps_xy_diagonal():
    cov = np.diag([1e-8, 1e-8, 1e-8, 4e-6, 9e-6])
    rel = RelativePose(np.eye(4), cov, Status.OK)
    np.testing.assert_allclose(velocity_variance(rel, 0.1), [4e-4, 9e-4, 6.5e-4])
    assert np.all(np.isnan(velocity_variance(RelativePose(np.eye(4), None, Status.OK), 0.1)))
    assert np.all(np.isnan(velocity_variance(rel, 0.0)))
