"""Loop closure in fixed-lag smoothing (planodom.smoothing.windowed_loops) on the synthetic
closed loop of the batch tests: old landmarks re-enter the window from their marginals."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.smoothing.batch import group_by_epoch
from planodom.smoothing.loop_records import reidentification_counts
from planodom.smoothing.windowed import WindowedSmoother, smooth_windowed
from tests.smoothing.test_loop_closure import _config, _end_error, _loop_problem


@pytest.fixture(scope="module")
def problem():
    return _loop_problem()


def _windowed(loop_closure: bool) -> PlanodomConfig:
    return _config(False).updated({"smoothing.windowed_loop_closure": loop_closure})


def test_fixed_lag_loop_closure_removes_the_drift_at_the_loop_end(problem):
    truth, planes, relatives = problem
    without = smooth_windowed(planes, relatives, _windowed(False))
    smoother = WindowedSmoother(_windowed(True))
    by_epoch = group_by_epoch(relatives, len(planes))
    for k, epoch in enumerate(planes):
        smoother.add_epoch(epoch, by_epoch[k])
    with_lc = smoother.result()
    assert smoother.loops is not None
    ties = smoother.loops.reidentifications
    assert len(ties) >= 20
    assert reidentification_counts(ties)["wrong_kept"] == 0
    # the tied landmarks had left the window (4 epochs, 20 epochs' gap): they re-entered
    assert smoother.loops.reentered >= 3
    assert _end_error(without.poses, truth) > 0.4  # the fixed-lag smoother follows the drift
    assert _end_error(with_lc.poses, truth) < 0.6 * _end_error(without.poses, truth)
    # the map reaches the newest estimate too (real-time output)
    assert with_lc.online_poses is not None
    assert _end_error(with_lc.online_poses, truth) < 0.6 * _end_error(without.poses, truth)


def test_the_marginal_kept_is_the_landmarks_information(problem):
    """A re-entered landmark's prior is its joint marginal when it left: its
    information is positive definite, and its mean the estimate then."""
    _, planes, relatives = problem
    smoother = WindowedSmoother(_windowed(True))
    by_epoch = group_by_epoch(relatives, len(planes))
    for k, epoch in enumerate(planes[:30]):
        smoother.add_epoch(epoch, by_epoch[k])
    assert smoother.loops is not None and smoother.loops.marginals
    for j, (factor, point) in smoother.loops.marginals.items():
        assert factor.error(point) >= 0.0
        lm = smoother.loops.landmarks[j]
        assert point.exists(lm.key)
        assert np.isfinite(factor.error(point))
