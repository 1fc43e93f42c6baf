"""The deskewing error of epochs kept without deskewing (planodom.smoothing.undeskewed)
against its closed form from known constant twists, and where the batch's covariances
take it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from planodom.config import SmoothingConfig
from planodom.odometry.relative import RelativePose
from planodom.se3 import se3_exp
from planodom.smoothing.batch_covariances import sandwich_inputs
from planodom.smoothing.undeskewed import undeskewed_errors, with_undeskewed

DT = 0.1  # s between epochs


def _steps(twists: np.ndarray, kept: set[int], times: tuple[float, float]) -> list[RelativePose]:
    """delta = 1 steps of constant twists (E - 1, 6) per DT, epoch k (in ``kept``) kept
    without deskewing, the others deskewed with their twist; points over ``times``."""
    return [
        RelativePose(se3_exp(w * DT), None, prev=k - 1, curr=k, time_spread=True,
                     deskew_twist=None if k in kept else w, deskew_times=times, interval_s=DT)
        for k, w in enumerate(twists, start=1)
    ]  # fmt: skip


def test_errors_are_the_motion_over_the_points() -> None:
    rng = np.random.default_rng(0)
    twists = rng.normal(0.0, 0.5, (6, 6))  # steps into epochs 1..6
    span = 0.08
    d = undeskewed_errors(_steps(twists, {2, 4, 6}, (0.0, span)), 7)
    # the points after the epoch's time: the step out of it; the last epoch: the one in
    np.testing.assert_allclose(d[2], -span * twists[2], atol=1e-12)
    np.testing.assert_allclose(d[4], -span * twists[4], atol=1e-12)
    np.testing.assert_allclose(d[6], -span * twists[5], atol=1e-12)
    assert np.all(np.isnan(d[[0, 1, 3, 5]]))  # deskewed, or the first epoch
    # a sweep centred on the epoch's time: half the step in, half the step out
    centred = undeskewed_errors(_steps(twists, {3}, (-0.04, 0.04)), 7)
    np.testing.assert_allclose(centred[3], -0.04 * 0.5 * (twists[2] + twists[3]), atol=1e-12)
    # epochs taken at one instant have nothing to deskew
    instant = [
        replace(r, time_spread=False, deskew_times=None) for r in _steps(twists, {2}, (0.0, span))
    ]
    assert np.all(np.isnan(undeskewed_errors(instant, 7)))


def test_with_undeskewed_adds_the_squared_motion_on_those_epochs_only() -> None:
    twists = np.random.default_rng(1).normal(0.0, 0.5, (5, 6))
    rels = _steps(twists, {3}, (0.0, DT))
    Q = np.stack([np.diag(np.full(6, 1e-6 * (k + 1))) for k in range(6)])
    out = with_undeskewed(Q, rels)
    d = -DT * twists[3]
    np.testing.assert_allclose(out[3], Q[3] + np.diag(d**2), atol=1e-15)
    assert np.array_equal(np.delete(out, 3, axis=0), np.delete(Q, 3, axis=0))
    assert with_undeskewed(Q, _steps(twists, set(), (0.0, DT))) is Q


def test_sandwich_inputs_take_it_only_when_asked() -> None:
    """With "motion" (the default) the sandwich adds the squared motion to the kept
    epoch's ``Q_k``, "none" leaves the previous release's ``Q``; "fitted" reads neither."""
    twists = np.random.default_rng(2).normal(0.0, 0.5, (9, 6))
    rels = _steps(twists, {4}, (0.0, DT))
    on, _ = sandwich_inputs(SmoothingConfig(covariance_model="sandwich"), {}, rels, 10)
    off, _ = sandwich_inputs(
        SmoothingConfig(covariance_model="sandwich", sandwich_undeskewed="none"), {}, rels, 10
    )
    assert SmoothingConfig().sandwich_undeskewed == "motion"
    assert on is not None and off is not None
    np.testing.assert_allclose(on[4] - off[4], np.diag((DT * twists[4]) ** 2), atol=1e-15)
    assert np.array_equal(np.delete(on, 4, axis=0), np.delete(off, 4, axis=0))
    fitted = SmoothingConfig(covariance_model="fitted")
    assert sandwich_inputs(fitted, {}, rels, 10) == (None, None)
