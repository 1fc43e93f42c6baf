"""The plane-map pipeline's trend twist (:func:`planodom.odometry.deskew.trend_twist`)."""

from __future__ import annotations

import numpy as np

from planodom.odometry.deskew import trend_twist


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
