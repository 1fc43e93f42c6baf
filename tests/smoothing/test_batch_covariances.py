"""``smoothing.covariance_model`` "auto": the sandwich where its inputs exist, else the
fitted covariances (compared bit for bit with the explicit models' runs)."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import SmoothingConfig
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.batch_covariances import NO_JACOBIANS
from planodom.smoothing.diagnostics import smoother_metrics
from planodom.smoothing.synthetic import make_sequence, with_deskew_jacobians


def _sequence(jacobians: bool, spread: bool) -> tuple[list, list]:
    """30 epochs with known noise; the planes with random deskewing Jacobians or none,
    the relative poses of scans spread in time or taken at one instant."""
    seq = make_sequence(30, seed=4, sigma_rotation=2e-4, sigma_translation=5e-3,
                        sigma_normal=1e-3, sigma_offset=5e-3)  # fmt: skip
    return with_deskew_jacobians(seq, jacobians=jacobians, spread=spread)


@pytest.mark.parametrize(
    ("jacobians", "spread", "chosen", "note"),
    [
        (True, True, "sandwich", None),
        (False, True, "fitted", NO_JACOBIANS),
        (True, False, "fitted", None),
    ],
)
def test_auto_picks_the_sandwich_where_its_inputs_exist(
    jacobians: bool, spread: bool, chosen: str, note: str | None
) -> None:
    """The "auto" model gives the covariances of the model it names, bit for bit, the same poses,
    and says why it fell back only where the scans are spread in time without the
    planes' Jacobians."""
    planes, relatives = _sequence(jacobians, spread)
    base = SmoothingConfig(loop_closure=False)
    assert base.covariance_model == "auto"
    auto = smooth_batch(planes, relatives, base)
    explicit = smooth_batch(planes, relatives, base.model_copy(update={"covariance_model": chosen}))
    assert auto.covariance_model == chosen
    assert auto.covariances is not None and explicit.covariances is not None
    assert np.array_equal(auto.covariances, explicit.covariances)
    assert np.array_equal(auto.poses, explicit.poses)
    assert auto.covariance_note == note
    metrics = smoother_metrics(auto)
    assert metrics["covariance_model"] == chosen
    assert metrics.get("covariance_note") == note


def test_auto_is_fitted_with_rescaled_noise_models() -> None:
    """With ``covariance_scale`` (the noise models rescaled) "auto" is "fitted"."""
    planes, relatives = _sequence(True, True)
    base = SmoothingConfig(loop_closure=False, covariance_scale="posterior")
    auto = smooth_batch(planes, relatives, base)
    fitted = smooth_batch(planes, relatives, base.model_copy(update={"covariance_model": "fitted"}))
    assert auto.covariance_model == "fitted" and auto.covariance_note is None
    assert auto.covariances is not None and fitted.covariances is not None
    assert np.array_equal(auto.covariances, fitted.covariances)


def test_explicit_sandwich_keeps_its_path_without_jacobians() -> None:
    """An explicit "sandwich" without any plane's Jacobian is not rerouted (no note): its
    extra term is zero, so it equals the fitted covariances to round-off."""
    planes, relatives = _sequence(False, True)
    base = SmoothingConfig(loop_closure=False, covariance_model="sandwich")
    sandwich = smooth_batch(planes, relatives, base)
    fitted = smooth_batch(planes, relatives, base.model_copy(update={"covariance_model": "fitted"}))
    assert sandwich.covariance_model == "sandwich" and sandwich.covariance_note is None
    assert sandwich.covariances is not None and fitted.covariances is not None
    np.testing.assert_allclose(sandwich.covariances, fitted.covariances, rtol=1e-6, atol=1e-15)
