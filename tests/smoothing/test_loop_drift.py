"""The run's own drift (planodom.smoothing.loop_drift): closed forms."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.smoothing.loop_drift import RunWalk, run_drift, run_drift_xy


def test_run_walk_grows_as_a_velocity_random_walk_and_restarts():
    walk = RunWalk()
    steps = [np.array([1.0, 0.0]), np.array([1.2, 0.1]), np.array([0.9, -0.1])]
    assert [walk.variance(s, 0.01) for s in steps] == [0.01] * 3  # measured: their own
    sigma2 = (0.2**2 + 0.1**2 + 0.3**2 + 0.2**2) / 2  # mean squared change, both axes
    for n in (1, 2, 3):
        assert walk.variance(None, 10.0) == pytest.approx(sigma2 * (n**3 - (n - 1) ** 3) / 3)
    assert walk.variance(None, 0.5) == 0.5  # capped by the fallback's
    assert walk.variance(np.array([1.0, 0.0]), 0.01) == 0.01  # no predecessor: no change
    assert walk.change[1] == 2 and walk.variance(None, 10.0) == pytest.approx(sigma2 / 3)
    assert RunWalk().variance(None, 0.25) == 0.25  # nothing measured yet: the fallback's


def test_run_drift_closed_form():
    cfg = PlanodomConfig()
    travelled = np.array([0.0, 1.0, 3.0, 6.0])
    variances = np.array([[0.0, 0.0], [0.1, 1e-4], [0.3, 2e-4], [0.4, 5e-4]])
    cov = run_drift(travelled, variances, [(3, 1), (0, 1)], cfg)
    s = cfg.smoothing
    var_r, distance, var_t = 4e-4 + 1e-4, 5.0 + 1.0, 0.3 + 0.1
    floor_t = (s.loop_min_translation_m / s.loop_sigmas) ** 2
    floor_r = np.radians(cfg.association.prior_rotation_deg) / s.loop_sigmas
    var_xy = var_t / 2 + var_r * distance**2 + floor_t
    np.testing.assert_allclose(cov, np.diag([var_r + floor_r**2, var_xy, var_xy]))


def test_run_drift_xy_closed_form_per_span_set():
    cfg = PlanodomConfig()
    s = cfg.smoothing
    travelled = np.array([0.0, 1.0, 3.0, 6.0])
    variances = np.array([[0.0, 0.0], [0.1, 1e-4], [0.3, 2e-4], [0.4, 5e-4]])
    # span sets ((3, 1), (0, 1)) and ((2, 2), (0, 3))
    spans = [(np.array([3, 2]), np.array([1, 2])), (np.array([0, 0]), np.array([1, 3]))]
    xy = run_drift_xy(travelled, variances, spans, cfg)
    floor_t = (s.loop_min_translation_m / s.loop_sigmas) ** 2
    first = (0.3 + 0.1) / 2 + (4e-4 + 1e-4) * (5.0 + 1.0) ** 2 + floor_t
    second = 0.4 / 2 + 5e-4 * 6.0**2 + floor_t
    np.testing.assert_allclose(xy, [first, second], rtol=1e-12)
