"""Epoch times: the next one, checked, and gaps in them (scans missing), also against the
truth of a simulated recording with an hour cut out."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.errors import GeometryError
from planodom.geometry import invert_transform
from planodom.odometry import run_odometry
from planodom.odometry.epoch_time import (
    RESET_PERIODS,
    epoch_periods,
    is_gap,
    lower_quartile,
    next_epoch_time,
)
from planodom.simulation import simulate_named


def test_next_epoch_time_refuses_a_time_that_does_not_increase():
    assert next_epoch_time(None, [], 0.1) == 0.0
    assert next_epoch_time(None, [1.0], 0.1) == pytest.approx(1.1)
    with pytest.raises(GeometryError, match="must increase"):
        next_epoch_time(1.0, [1.0], 0.1)


def test_epoch_periods_by_the_lower_quartile_of_the_steps():
    # steps of 0.1 s, one of 0.3 s (two scans missing) and one of an hour
    times = np.cumsum([0.0, 0.1, 0.1, 0.3, 0.1, 0.1, 3600.0, 0.1])
    np.testing.assert_array_equal(epoch_periods(times), [1, 1, 3, 1, 1, 36000, 1])
    np.testing.assert_array_equal(epoch_periods([0.0, 0.0]), [1])  # no positive step
    assert len(epoch_periods([5.0])) == 0


def test_is_gap_judged_by_the_steps_so_far():
    times = [0.0, 0.1, 0.2]
    assert not is_gap(times, 0.3) and not is_gap(times, 0.349)  # 1.49 periods
    assert is_gap(times, 0.2 + 0.1 * RESET_PERIODS) and is_gap(times, 3600.0)
    assert not is_gap(times, 0.2 + 0.1 * (RESET_PERIODS - 1))  # a few scans dropped
    # judged by the recent steps: an early slow stretch does not hide a later gap
    slow_then_fast = [*np.arange(0.0, 100.0, 1.0), *np.arange(100.0, 120.0, 0.1)]
    assert is_gap(slow_then_fast, slow_then_fast[-1] + 0.1 * RESET_PERIODS)
    assert not is_gap([0.0], 3600.0)  # one step: no period to judge it by
    assert not is_gap([0.0, 0.1, 0.2, 0.3], 0.31)  # a short step is no gap


def _step_errors_m(run, poses: np.ndarray) -> np.ndarray:
    """(N - 1,) translation error of every estimated step against the simulator's, m."""
    true = invert_transform(run.poses[:-1]) @ run.poses[1:]
    est = invert_transform(poses[:-1]) @ poses[1:]
    return np.linalg.norm((invert_transform(true) @ est)[:, :3, 3], axis=1)


def test_no_motion_carried_across_an_hour_cut_out_of_a_recording():
    """A lidar16 recording at 4 m/s with an hour cut out before epoch 5: the step across
    the cut's twist (0.4 m over 3600 s) had deskewed epoch 5 as standing still, 13 cm off
    and 'ok' (9 and 4 cm the next two). No motion is carried across the gap now: the epoch
    after it is deskewed with the twist held from before, and as good as without the cut.
    """
    run = simulate_named("paper-loop", "lidar16", noise=0.0, seed=1, n_epochs=8, speed=4.0)
    times = np.asarray(run.times, dtype=np.float64).copy()
    times[5:] += 3600.0
    cut = run_odometry(run, PlanodomConfig(), run.rig, times=times)
    whole = run_odometry(run, PlanodomConfig(), run.rig)
    assert all(r.status == "ok" for r in cut.results[1:])
    e_cut, e_whole = _step_errors_m(run, cut.poses), _step_errors_m(run, whole.poses)
    assert e_whole.max() < 0.005  # the recording without the cut: a few mm
    assert e_cut.max() < 0.01, e_cut  # 13 cm before


def test_lower_quartile_is_numpys_percentile_bit_for_bit():
    rng = np.random.default_rng(7)
    for n in [1, 2, 3, 4, 5, 8, 9, 100, 101]:
        for _ in range(50):
            v = rng.exponential(0.1, n) * rng.choice([1.0, 1e-6, 1e6])
            if n > 3:
                v[rng.integers(0, n, 2)] = v[0]  # ties
            assert lower_quartile(list(v)) == float(np.percentile(v, 25))


def test_is_gap_as_the_periods_of_the_recent_steps():
    """is_gap against epoch_periods over the same recent steps (numpy's percentile)."""
    rng = np.random.default_rng(3)
    for n in [2, 3, 10, 150]:
        for _ in range(40):
            steps = rng.choice([0.1, 0.1, 0.1, 0.2, 0.3], n) * rng.uniform(0.9, 1.1, n)
            times = list(np.cumsum(steps))
            for t in times[-1] + 0.1 * np.array([1.0, 9.4, 9.5, 9.6, 10.0, 10.5, 11.0, 1e4]):
                recent = [*times[-101:], t]
                expected = bool(epoch_periods(recent)[-1] >= RESET_PERIODS)
                assert is_gap(times, float(t)) == expected
