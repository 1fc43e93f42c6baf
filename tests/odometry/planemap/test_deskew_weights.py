"""The deskewing error in a scan's registration weights (planodom.odometry.planemap.
deskew_weights): the led twist's term against Monte Carlo refits of the re-deskewed points."""

from __future__ import annotations

import numpy as np

from planodom.config import PlanemapConfig
from planodom.extraction.deskew import deskew_points
from planodom.geometry import Plane
from planodom.odometry.planemap.deskew_weights import change_covariance, led_weights
from tests.odometry.test_plane_deskew import TRUE_TWIST, _fit, _plane_with_jacobian, _wall_epoch

ON = PlanemapConfig(lead_weights="stated", led_bias_m=0.003)


def test_the_led_term_is_the_refits_covariance_under_the_led_twists_error():
    """Twists drawn with the per-axis variance ``var`` (unequal axes: a wrong axis order
    fails), the points deskewed again with each and the plane refitted: the sample
    covariance of (n, d) is the term, within sampling error (3000 draws)."""
    rng = np.random.default_rng(11)
    var = np.array([np.radians(0.5), np.radians(0.1), np.radians(2.0), 0.05, 0.2, 0.02]) ** 2
    p_t, t = _wall_epoch(rng, [1.0, 0.2, 0.1], 6.0)
    plane = _plane_with_jacobian(p_t, t, TRUE_TWIST)
    span = float(np.max(np.abs(t)))
    got = led_weights(ON, [plane], np.array([0]), (var, span))
    assert got is not None
    bias, term = got
    assert bias == 0.003
    draws = TRUE_TWIST + rng.normal(size=(3000, 6)) * np.sqrt(var)
    fits = np.array([_fit(deskew_points(p_t, t, xi)) for xi in draws])
    sample = np.cov(fits.T)
    w, V = np.linalg.eigh(term[0])
    along = np.einsum("ij,jk,ki->i", V.T, sample, V)
    big = w > 1e-2 * w.max()  # below it the refits' second-order change shows
    np.testing.assert_allclose(along[big], w[big], rtol=0.1)
    assert np.linalg.norm(sample - term[0]) <= 0.08 * np.linalg.norm(term[0])


def test_off_or_not_led_gives_nothing_and_a_plane_without_jacobian_no_term():
    rng = np.random.default_rng(2)
    p_t, t = _wall_epoch(rng, [0.1, 1.0, 0.0], 3.0, n=100)
    plane = _plane_with_jacobian(p_t, t, TRUE_TWIST)
    bare = Plane(plane.normal, plane.offset)
    led = (np.full(6, 1e-4), 0.05)
    assert led_weights(PlanemapConfig(), [plane], np.array([0]), led) is None
    assert led_weights(ON, [plane], np.array([0]), None) is None
    got = led_weights(ON, [bare, plane], np.array([0, 1]), led)
    assert got is not None
    assert np.all(got[1][0] == 0.0) and np.any(got[1][1] != 0.0)


def test_the_change_covariance_is_the_deviations_mean_square_over_three_per_axis():
    rng = np.random.default_rng(5)
    p_t, t = _wall_epoch(rng, [1.0, 0.0, 0.0], 4.0, n=100)
    plane = _plane_with_jacobian(p_t, t, TRUE_TWIST)
    config = PlanemapConfig(deskew_variance="twist_change")
    sse, n = np.array([3.0e-6, 1.2e-4]), np.array([4, 3])
    got = change_covariance(config, [plane], np.array([0]), sse, n)
    assert got is not None
    D = np.asarray(plane.deskew_jacobian)
    per_axis = np.r_[np.full(3, 3.0e-6 / 4 / 3), np.full(3, 1.2e-4 / 3 / 3)]
    np.testing.assert_allclose(got[0], D @ np.diag(per_axis) @ D.T)
    assert change_covariance(PlanemapConfig(), [plane], np.array([0]), sse, n) is None
    assert change_covariance(config, [plane], np.array([0]), sse, np.zeros(2, int)) is None
