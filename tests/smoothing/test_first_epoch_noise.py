"""The first epoch's deskewing error from its first step (planodom.smoothing.first_epoch_noise)
against a Monte Carlo of deskewing with a noisy first step's twist, and where the batch's
covariances take it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from planodom.config import SmoothingConfig
from planodom.odometry.relative import RelativePose, Status
from planodom.se3 import se3_exp, se3_log
from planodom.smoothing.batch_covariances import sandwich_inputs
from planodom.smoothing.first_epoch_noise import first_step_covariance, with_first_step

DT = 0.1  # s between epochs
SPAN = 0.07  # s, the points' times after the epoch's stamp


def _step(cov: np.ndarray, sigma_z: float = np.inf) -> RelativePose:
    """The step 0 -> 1 of a slow constant twist, declared covariance ``cov`` (5, 5)."""
    w = np.array([0.01, -0.02, 0.05, 1.5, 0.2, 0.05])  # rad/s, m/s
    return RelativePose(
        se3_exp(w * DT), cov, prev=0, curr=1, time_spread=True, deskew_twist=w,
        deskew_times=(0.0, SPAN), interval_s=DT, z_observed=np.isfinite(sigma_z),
        sigma_z=sigma_z,
    )  # fmt: skip


def test_the_first_step_twists_error_over_the_span() -> None:
    rng = np.random.default_rng(3)
    L = rng.normal(0.0, 1.0, (5, 5)) * np.array([1e-4, 1e-4, 1e-4, 1e-3, 1e-3])[:, None]
    cov = L @ L.T + np.diag([1e-9, 1e-9, 1e-9, 1e-7, 1e-7])
    sigma_z = 2e-3
    step = _step(cov, sigma_z)
    # Monte Carlo: the step measured with its declared error (roll pitch yaw x y z in the
    # tangent, z from sigma_z), the first epoch deskewed with its twist over SPAN
    n = 40000
    noise = np.zeros((n, 6))
    noise[:, :5] = rng.multivariate_normal(np.zeros(5), cov, n)
    noise[:, 5] = rng.normal(0.0, sigma_z, n)
    measured = se3_exp(noise) @ step.T_prev_curr
    error = SPAN * (se3_log(measured) - se3_log(step.T_prev_curr)) / DT
    want = np.cov(error.T)
    got = first_step_covariance([step])
    assert got is not None
    scale = np.sqrt(np.outer(np.diag(want), np.diag(want)))
    np.testing.assert_allclose(got / scale, want / scale, atol=0.03)  # 40000 draws: ~0.01
    # z unmeasured: no vertical part from the step
    flat = first_step_covariance([replace(step, z_observed=False, sigma_z=np.inf)])
    assert flat is not None and flat[5, 5] == 0.0
    np.testing.assert_allclose(flat[:5, :5], got[:5, :5])


def test_none_without_a_usable_first_step() -> None:
    step = _step(np.eye(5) * 1e-6)
    assert first_step_covariance([replace(step, status=Status.UNRESOLVED)]) is None
    assert first_step_covariance([replace(step, covariance=None)]) is None
    assert first_step_covariance([replace(step, time_spread=False, deskew_times=None)]) is None
    assert first_step_covariance([replace(step, prev=1, curr=2)]) is None
    assert first_step_covariance([]) is None


def test_added_to_the_first_epoch_only_and_taken_by_the_sandwich_inputs() -> None:
    step = _step(np.diag([1e-6, 2e-6, 3e-6, 4e-4, 5e-4]), sigma_z=0.01)
    Q = np.stack([np.diag(np.full(6, 1e-8 * (k + 1))) for k in range(3)])
    out = with_first_step(Q, [step])
    add = np.diag([1e-6, 2e-6, 3e-6, 4e-4, 5e-4, 1e-4]) * (SPAN / DT) ** 2
    np.testing.assert_allclose(out[0], Q[0] + add, rtol=1e-12)
    assert np.array_equal(out[1:], Q[1:])
    assert with_first_step(Q, [replace(step, status=Status.UNRESOLVED)]) is Q
    # the batch's sandwich inputs: off by default, added with "step"
    rels = [step, replace(step, prev=1, curr=2)]
    base = SmoothingConfig(covariance_model="sandwich")
    Q0, _ = sandwich_inputs(base, {}, rels, 3)
    step_cfg = SmoothingConfig(covariance_model="sandwich", sandwich_first_epoch="step")
    Q1, _ = sandwich_inputs(step_cfg, {}, rels, 3)
    assert Q0 is not None and Q1 is not None
    np.testing.assert_allclose(Q1[0], Q0[0] + add, rtol=1e-9, atol=1e-18)
    assert np.array_equal(Q1[1:], Q0[1:])


def test_degenerate_only_where_the_first_step_did_not_measure_its_translation() -> None:
    step = _step(np.diag([1e-6, 2e-6, 3e-6, 4e-4, 5e-4]))
    assert first_step_covariance([step], degenerate_only=True) is None  # status OK
    degenerate = replace(step, status=Status.DEGENERATE)
    got = first_step_covariance([degenerate], degenerate_only=True)
    assert got is not None
    np.testing.assert_array_equal(got, first_step_covariance([step]))
    Q = np.zeros((2, 6, 6))
    assert with_first_step(Q, [step], degenerate_only=True) is Q
    cfg = SmoothingConfig(covariance_model="sandwich", sandwich_first_epoch="degenerate_step")
    rels = [step, replace(step, prev=1, curr=2)]
    Q_ok, _ = sandwich_inputs(cfg, {}, rels, 3)
    base, _ = sandwich_inputs(SmoothingConfig(covariance_model="sandwich"), {}, rels, 3)
    assert Q_ok is not None and base is not None
    np.testing.assert_array_equal(Q_ok, base)  # a measured first step: nothing added
