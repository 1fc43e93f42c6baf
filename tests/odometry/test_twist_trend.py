"""The trend twist (:func:`planodom.odometry.trend.trend_twist`): plane-map and pairwise."""

from __future__ import annotations

from collections import deque

import numpy as np

from planodom.odometry.trend import column_median, predicted_twist, trend_twist


def test_a_steady_change_is_extrapolated_one_epoch():
    """Twists changing by a constant amount per epoch (a turn that tightens, with a small
    wobble) give the next epoch's twist, where their mean lags by half the window."""
    rng = np.random.default_rng(3)
    step = np.array([0.0, 0.0, 0.06, 0.1, 0.0, 0.0])  # per epoch
    recent = np.outer(np.arange(5), step) + 1e-4 * rng.standard_normal((5, 6))
    expected = 5 * step
    got = trend_twist(recent)
    np.testing.assert_allclose(got[[2, 3]], expected[[2, 3]], atol=2e-3)
    assert np.linalg.norm(recent.mean(axis=0) - expected) > 0.1


def test_a_shaking_rate_is_averaged():
    """A rate alternating around a constant (suspension roll) has no trend its residuals
    determine: the prediction is the mean, not a line through the last swing."""
    recent = np.zeros((5, 6))
    recent[:, 0] = 0.05 * np.array([1, -1, 1, -1, 1.0]) + 0.01 * np.arange(5) / 4
    got = trend_twist(recent)
    mean = recent.mean(axis=0)
    np.testing.assert_allclose(got, mean, atol=1e-12)


def test_twists_at_given_epochs_are_extrapolated_to_the_asked_one():
    """With the epochs they were measured at (a gap of unresolved epochs among them), a
    steady change is extrapolated to the epoch asked for: the line through them there."""
    step = np.array([0.0, 0.0, 0.02, 0.0, 0.0, 0.0])
    x = np.array([3, 4, 6, 7, 8])
    recent = np.outer(x, step) + np.array([0.0, 0.0, 0.2, 3.0, 0.0, 0.0])
    got = trend_twist(recent, x, 11.0)
    np.testing.assert_allclose(got, 11 * step + [0.0, 0.0, 0.2, 3.0, 0.0, 0.0], atol=1e-12)
    # without epochs: one an epoch, the next one after the last
    np.testing.assert_allclose(trend_twist(recent), trend_twist(recent, np.arange(5), 5.0))


def test_the_pairwise_trend_takes_the_rate_from_the_trend_and_the_velocity_given():
    from planodom.config import OdometryConfig
    from planodom.odometry.trend import pairwise_trend

    rate = np.array([0.0, 0.0, 0.2, 0.0, 0.0, 0.0])
    recent = [(k, (0.1 + 0.01 * k) * rate / 0.2 + [0, 0, 0, 5.0, 0, 0]) for k in range(5)]
    base = np.array([0.0, 0.0, 0.0, 2.0, 0.1, 0.0])
    on = OdometryConfig(pairwise_trend_rescue=True)
    got = pairwise_trend(recent, 7, base, on)
    assert got is not None
    np.testing.assert_allclose(got[:3], [0.0, 0.0, 0.17], atol=1e-12)
    np.testing.assert_array_equal(got[3:], base[3:])
    assert pairwise_trend(recent[:3], 7, base, on) is None
    assert pairwise_trend(recent, 7, None, on) is None
    assert pairwise_trend(recent, 7, base, OdometryConfig()) is None  # off by default


def test_the_plane_maps_prediction_is_the_mean_of_the_recent_twists_or_the_last():
    """Against a plane map the prediction is the mean of the recent twists
    (``planemap.prediction: mean``) or the last one (``last``); either way the twist joins
    the recent ones (the trend rescue reads them) and no velocity is kept."""
    rng = np.random.default_rng(7)
    twists = rng.standard_normal((4, 6))
    for last in (False, True):
        recent: deque[np.ndarray] = deque(maxlen=3)
        velocities: deque[np.ndarray] = deque(maxlen=3)
        for tw in twists:
            got = predicted_twist(tw, True, recent, velocities, True, "last" if last else "mean")
        expected = twists[-1] if last else twists[-3:].mean(axis=0)
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-15)
        assert len(recent) == 3 and not velocities
        assert got is not twists[-1]


def test_the_plane_maps_trend_prediction_extrapolates_a_steady_change():
    """``planemap.prediction: trend``: twists changing by the same amount each epoch (a
    sway's rate through its zero) give the next one exactly (a line's residuals are zero:
    no shrinking), where the mean lags by half the window; before 4 twists, the mean."""
    step = np.array([0.01, -0.02, 0.03, 0.1, 0.0, -0.05])  # per epoch
    start = np.array([0.1, 0.0, -0.2, 2.0, 0.1, 0.0])
    recent: deque[np.ndarray] = deque(maxlen=5)
    velocities: deque[np.ndarray] = deque(maxlen=5)
    for k in range(7):
        got = predicted_twist(start + k * step, True, recent, velocities, True, "trend")
        if k < 3:
            np.testing.assert_allclose(got, start + 0.5 * k * step, rtol=0, atol=1e-15)
        else:
            np.testing.assert_allclose(got, start + (k + 1) * step, rtol=0, atol=1e-12)
    assert len(recent) == 5 and not velocities


def test_the_map_trend_rescue_tries_the_mean_when_the_trend_is_the_prediction():
    """With ``planemap.prediction: trend`` the epoch was first deskewed with the trend:
    the rescue then tries the recent twists' mean (with ``mean``, the trend)."""
    from planodom.config import OdometryConfig
    from planodom.odometry.trend import map_trend

    recent = [np.r_[0.0, 0.0, 0.1 * k, 1.0, 0.0, 0.0] for k in range(5)]
    config = OdometryConfig()
    np.testing.assert_allclose(map_trend(recent, config, "trend"), np.mean(recent, axis=0))
    np.testing.assert_allclose(map_trend(recent, config, "mean"), trend_twist(np.array(recent)))
    assert map_trend(recent[:3], config, "trend") is None


def test_column_median_is_numpys_median_bit_for_bit():
    rng = np.random.default_rng(11)
    for w in range(1, 9):
        for _ in range(200):
            rows = rng.normal(0.0, 3.0, (w, 3)) * rng.choice([1.0, 1e-9, 1e9])
            if w > 2:
                rows[rng.integers(0, w), :] = rows[0]  # ties
                rows[rng.integers(0, w), 1] = 0.0
            np.testing.assert_array_equal(column_median(rows), np.median(rows, axis=0))
            assert column_median(rows).tobytes() == np.median(rows, axis=0).tobytes()


def test_predicted_twist_median_velocity_of_the_measured_steps():
    """The rate of the step and the per-axis median of the measured velocities (numpy's)."""
    velocities: deque[np.ndarray] = deque(maxlen=5)
    rng = np.random.default_rng(5)
    for k in range(8):
        twist = rng.normal(0.0, 1.0, 6)
        got = predicted_twist(twist, k != 3, deque(), velocities, against_map=False)
        want = np.concatenate((twist[:3], np.median(np.array(velocities), axis=0)))
        assert got.tobytes() == want.tobytes()
