"""The windowed initial guess checked against the chained odometry (``batch_initial: checked``):
the chain against the true poses it was measured from, the span test against its closed
form, and the choice on a corridor the guess slid along."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from planodom.config import PlanodomConfig
from planodom.geometry import invert_transform
from planodom.odometry.relative import RelativePose, Status
from planodom.smoothing.initial_check import (
    _Chain,
    checked_guess,
    inconsistent_spans,
    run_history,
)

CONFIG = PlanodomConfig()
STEP_SIGMA = 0.01  # m, per axis, of a measured step
YAW_SIGMA = 0.002  # rad


def _pose(x: float, y: float, yaw: float) -> np.ndarray:
    T = np.eye(4)
    c, s = np.cos(yaw), np.sin(yaw)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:2, 3] = x, y
    return T


def _truth(n: int) -> np.ndarray:
    """(n, 4, 4) a vehicle speeding up along a gentle curve (0.15 m to 0.2 m a step)."""
    s = np.cumsum(np.linspace(0.15, 0.2, n)) - 0.15
    yaw = 0.004 * np.arange(n)
    return np.stack([_pose(5 * np.sin(si / 5), 5 * (1 - np.cos(si / 5)), y)
                     for si, y in zip(s, yaw, strict=True)])  # fmt: skip


def _relatives(truth: np.ndarray, statuses: list[Status]) -> list[RelativePose]:
    """delta = 1 relative poses of ``truth``, exact, with ``statuses[k]`` into epoch k;
    an unresolved one carries the constant-velocity prediction (the step before)."""
    cov = np.diag([1e-6, 1e-6, YAW_SIGMA**2, STEP_SIGMA**2, STEP_SIGMA**2])
    out = []
    for k in range(1, len(truth)):
        T = invert_transform(truth[k - 1]) @ truth[k]
        if statuses[k] is Status.UNRESOLVED:
            T = invert_transform(truth[k - 2]) @ truth[k - 1]
        out.append(RelativePose(T, cov, statuses[k], prev=k - 1, curr=k))
    return out


def test_chain_reproduces_the_true_poses_it_was_measured_from() -> None:
    truth = _truth(40)
    chained = _Chain(CONFIG.smoothing).chain(_relatives(truth, [Status.OK] * 40), 40)
    np.testing.assert_allclose(chained, invert_transform(truth[0])[None] @ truth, atol=1e-9)


def test_chain_bridges_an_unresolved_epoch_by_its_prediction() -> None:
    """An unresolved epoch is chained by the odometry's prediction (its bridge), here the
    constant velocity of a vehicle at constant speed: the true poses."""
    n = 30
    truth = np.stack([_pose(0.2 * k, 0.0, 0.0) for k in range(n)])
    statuses = [Status.OK] * n
    statuses[20] = Status.UNRESOLVED
    chained = _Chain(CONFIG.smoothing).chain(_relatives(truth, statuses), n)
    np.testing.assert_allclose(chained[:, 0, 3], 0.2 * np.arange(n), atol=1e-9)


def test_run_history_sums_the_measured_steps_variances() -> None:
    truth = _truth(12)
    travelled, variances = run_history(truth, _relatives(truth, [Status.OK] * 12), CONFIG)
    steps = np.linalg.norm(np.diff(truth[:, :2, 3], axis=0), axis=1)
    np.testing.assert_allclose(travelled, np.append(0, np.cumsum(steps)))
    k = np.arange(12)
    np.testing.assert_allclose(variances[:, 0], k * 2 * STEP_SIGMA**2)
    np.testing.assert_allclose(variances[:, 1], k * YAW_SIGMA**2)


def test_span_test_is_the_closed_form_of_a_slide_along_the_travel() -> None:
    """A guess that slides 0.8 m along x from epoch 10 on, on a straight line: the worst
    span ends at 10 and starts where the run's variance is least: 0.8^2 / var_xy."""
    n = 25
    chained = np.stack([_pose(0.2 * k, 0.0, 0.0) for k in range(n)])
    windowed = chained.copy()
    windowed[10:, 0, 3] += 0.8
    travelled = 0.2 * np.arange(n)
    variances = np.stack([1e-4 * np.arange(n), np.zeros(n)], axis=1)
    c = CONFIG.smoothing
    worst, span = inconsistent_spans(chained, windowed, travelled, variances, CONFIG)
    floor = (c.loop_min_translation_m / c.loop_sigmas) ** 2
    assert span == (9, 10)
    np.testing.assert_allclose(worst, 0.8**2 / (0.5 * 1e-4 + floor))
    same, _ = inconsistent_spans(chained, chained, travelled, variances, CONFIG)
    assert same < 1e-20


def test_checked_guess_refuses_a_guess_slid_along_a_corridor() -> None:
    """40 rotation-only epochs of a corridor; a windowed guess that slid 3 m along it
    (the run's steps barely change, so its walk allows centimetres) is refused and the
    chained odometry returned; one within a few centimetres is kept."""
    n = 80
    truth = np.stack([_pose(0.16 * k + 1e-4 * k**1.5, 0.0, 0.0) for k in range(n)])
    statuses = [Status.OK] * 20 + [Status.DEGENERATE] * 40 + [Status.OK] * 20
    relatives = _relatives(truth, statuses)
    slid = truth.copy()
    slid[20:60, 0, 3] += np.linspace(0, 3.0, 40)
    slid[60:, 0, 3] += 3.0
    chained, worst, span = checked_guess(slid, relatives, CONFIG, None)
    assert chained is not None and worst > chi2.ppf(CONFIG.smoothing.loop_gate_quantile, 3)
    np.testing.assert_allclose(chained, truth, atol=1e-9)
    assert 19 <= span[0] < span[1] <= 61
    near = truth.copy()
    near[20:60, 0, 3] += np.linspace(0, 0.02, 40)
    near[60:, 0, 3] += 0.02
    assert checked_guess(near, relatives, CONFIG, None)[0] is None
