"""The run-level scale of the sandwich's deskewing error (planodom.smoothing.deskew_scale)
against seeded draws with a known scale."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from planodom.config import SmoothingConfig
from planodom.odometry.relative import RelativePose
from planodom.se3 import se3_exp, se3_log
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.deskew_scale import (
    axis_scales,
    deskew_differences,
    scaled_motion_change,
)
from planodom.smoothing.sandwich import deskew_motion_change
from planodom.smoothing.synthetic import make_sequence

DT = 0.1  # s between epochs
SPAN = 0.09  # s, the points' span


def _run(
    scales: np.ndarray, n: int = 3000, step_sigma: float = 0.0, seed: int = 0
) -> tuple[list[RelativePose], np.ndarray, np.ndarray]:
    """Relative poses of an ``n + 1``-epoch run whose deskewing errors (returned (n + 1, 6), rad
    and m per span) have the covariance ``diag(scales) Q_k diag(scales)`` (``Q_k`` diagonal,
    varying, returned (n + 1, 6, 6)), the steps exact in log space but for N(0,
    ``step_sigma``^2) per component of d (declared)."""
    rng = np.random.default_rng(seed)
    xi = np.cumsum(rng.normal(0.0, 0.05, (n + 1, 6)), axis=0)  # true twists, rad/s, m/s
    sig = rng.uniform(0.5e-3, 3e-3, (n + 1, 6))  # per epoch and axis, rad and m per span
    Q = np.zeros((n + 1, 6, 6))
    Q[:, range(6), range(6)] = sig**2
    Q[0] = 0.0  # the first epoch: no change of motion known
    cov = np.diag(np.full(5, (step_sigma * DT / SPAN) ** 2)) if step_sigma else None
    rels, err = [], np.full((n + 1, 6), np.nan)
    for k in range(1, n + 1):
        noise = rng.normal(0.0, step_sigma * DT / SPAN, 6) if step_sigma else np.zeros(6)
        T = se3_exp(xi[k - 1] * DT + noise)  # the step out of epoch k - 1 (its twist)
        twist = None
        if k < n:  # epoch k deskewed with its twist off by e_k / SPAN
            err[k] = scales * sig[k] * rng.standard_normal(6)
            twist = xi[k] + err[k] / SPAN
        rels.append(
            RelativePose(
                T,
                cov,
                prev=k - 1,
                curr=k,
                z_observed=True,
                sigma_z=step_sigma * DT / SPAN,
                time_spread=True,
                deskew_twist=twist,
                deskew_times=(0.0, SPAN) if k < n else None,
                interval_s=DT,
            )  # fmt: skip
        )
    return rels, Q, err


def test_differences_are_the_errors_for_exact_steps():
    rels, _, err = _run(np.ones(6), n=50)
    d, var = deskew_differences(rels, 51)
    assert np.all(np.isnan(d[0]))  # no deskewing twist recorded for the first epoch
    assert np.all(np.isnan(d[50]))  # no step out of the last epoch
    assert np.all(var == 0.0)
    # the step out of an epoch is its true twist over DT: d is the twist's error per span
    np.testing.assert_allclose(d[1:50], err[1:50], rtol=0, atol=1e-12)


def test_centred_sweep_takes_the_steps_into_and_out_of_the_epoch():
    rels, _, _ = _run(np.ones(6), n=20)
    twist = np.arange(1.0, 7.0) * 0.1
    rels[9] = RelativePose(
        **{**rels[9].__dict__, "deskew_twist": twist, "deskew_times": (-0.04, 0.04)}
    )
    d, _ = deskew_differences(rels, 21)
    rate_in = se3_log(rels[9].T_prev_curr) / DT  # the step into epoch 10
    rate_out = se3_log(rels[10].T_prev_curr) / DT
    np.testing.assert_allclose(d[10], 0.04 * (twist - 0.5 * (rate_in + rate_out)), atol=1e-15)


@pytest.mark.parametrize("seed", [0, 1])
def test_scale_recovered_from_seeded_draws(seed: int):
    truth = np.array([0.1, 0.2, 0.3, 0.5, 1.0, 2.0])
    rels, Q, _ = _run(truth, seed=seed)
    d, _ = deskew_differences(rels, len(Q))
    s = axis_scales(d, Q)
    # s^2 is a weighted mean of ~3000 chi2(1) draws: relative sd of s about 1.5 %
    np.testing.assert_allclose(s, truth, rtol=0.06)


def test_net_scale_takes_off_the_declared_step_noise():
    truth = np.full(6, 0.3)
    rels, Q, _ = _run(truth, step_sigma=1e-3, seed=3)
    d, var = deskew_differences(rels, len(Q))
    gross = axis_scales(d, Q)
    net = axis_scales(d, Q, var)
    assert np.all(gross > 1.5 * truth)  # the step's noise dominates the differences
    np.testing.assert_allclose(net, truth, rtol=0.15)


def test_unmeasured_vertical_keeps_the_changes_and_q_is_scaled():
    truth = np.full(6, 0.5)
    rels, Q, _ = _run(truth, n=400, seed=4)
    rels = [RelativePose(**{**r.__dict__, "z_observed": False}) for r in rels]
    scaled, s = scaled_motion_change(Q, rels)
    assert s[5] == 1.0
    np.testing.assert_allclose(s[:5], truth[:5], rtol=0.2)
    np.testing.assert_allclose(scaled, Q * np.outer(s, s)[None])


def test_batch_scales_the_sandwich_part_by_the_estimate():
    """smooth_batch with ``sandwich_motion_scale`` "run", the deskewing twists off the
    steps by exactly ``s`` times each epoch's changes' sigma: the sandwich's excess over
    the fitted covariances is ``s^2`` times that of "none" (the sandwich is linear in Q);
    the poses are the same."""
    seq = make_sequence(30, seed=4, sigma_rotation=2e-4, sigma_translation=5e-3,
                        sigma_normal=1e-3, sigma_offset=5e-3)  # fmt: skip
    rng = np.random.default_rng(5)
    planes = [[replace(p, deskew_jacobian=rng.normal(scale=0.2, size=(4, 6))) for p in ps]
              for ps in seq.planes]  # fmt: skip
    rels = [
        replace(r, time_spread=True, z_observed=True, sigma_z=1e-3, interval_s=DT)
        for r in seq.relatives
    ]
    Q = deskew_motion_change(rels, len(planes))
    s = 0.3
    steps = {r.prev: r for r in rels if r.delta == 1}
    out = []
    for r in rels:
        k = r.curr
        if r.delta == 1 and k in steps and np.any(Q[k]):
            rate = se3_log(steps[k].T_prev_curr) / DT
            offset = s * np.sqrt(np.diagonal(Q[k])) * np.where(k % 2, 1.0, -1.0)
            r = replace(r, deskew_twist=rate + offset / SPAN, deskew_times=(0.0, SPAN))
        out.append(r)
    _, scales = scaled_motion_change(Q, out)
    known = np.any(np.diagonal(Q, axis1=1, axis2=2) > 0.0, axis=0)  # (no vertical motion)
    assert np.sum(known) >= 5
    np.testing.assert_allclose(scales[known], s, rtol=1e-6)
    base = SmoothingConfig(
        loop_closure=False, covariance_model="sandwich", sandwich_motion_scale="none"
    )
    none = smooth_batch(planes, out, base)
    run = smooth_batch(planes, out, base.model_copy(update={"sandwich_motion_scale": "run"}))
    fitted = smooth_batch(planes, out, base.model_copy(update={"covariance_model": "fitted"}))
    assert np.array_equal(none.poses, run.poses) and np.array_equal(none.poses, fitted.poses)
    assert none.covariances is not None and run.covariances is not None
    assert fitted.covariances is not None
    np.testing.assert_allclose(
        run.covariances - fitted.covariances,
        s**2 * (none.covariances - fitted.covariances),
        rtol=1e-5,
        atol=1e-9 * np.max(np.abs(fitted.covariances)),
    )
