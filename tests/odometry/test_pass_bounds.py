from __future__ import annotations

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.geometry import transform_from_rpy_xyz
from planodom.odometry.pass_bounds import pass_bounds

_PRIOR = transform_from_rpy_xyz(0.0, 0.0, 0.1, 0.4, -0.2, 0.03)


@pytest.mark.parametrize("bound_by_prior", [True, False])
def test_prediction_keeps_the_prior_in_both_passes(bound_by_prior):
    cfg = PlanodomConfig().updated({"odometry.refine_unmeasured": "prediction"})
    b = pass_bounds(cfg, _PRIOR, bound_by_prior, 0.05)
    assert b.prediction is not None
    np.testing.assert_array_equal(b.prediction, _PRIOR[:3, 3])
    assert b.prediction_var == pytest.approx(0.05**2)
    a = cfg.association
    if bound_by_prior:
        np.testing.assert_array_equal(b.t0, _PRIOR[:3, 3])
        assert b.translation == a.prior_translation_m
    else:
        np.testing.assert_array_equal(b.t0, np.zeros(3))
        assert b.translation == a.max_translation_m
    assert b.rotation == pytest.approx(
        np.radians(a.prior_rotation_deg if bound_by_prior else a.max_rotation_deg)
    )
    assert b.z_prior == pytest.approx(0.03)


@pytest.mark.parametrize("mode", ["prior", "kept", "walls"])
def test_other_modes_and_an_unknown_sigma_keep_nothing(mode):
    cfg = PlanodomConfig().updated({"odometry.refine_unmeasured": mode})
    assert pass_bounds(cfg, _PRIOR, True, 0.05).prediction is None
    pred = PlanodomConfig().updated({"odometry.refine_unmeasured": "prediction"})
    for sigma in (None, np.inf):
        b = pass_bounds(pred, _PRIOR, True, sigma)
        assert b.prediction is None and b.prediction_var is None
    b = pass_bounds(pred, None, False, 0.05)
    assert b.prediction is None and b.z_prior == 0.0
