"""The batch's windowed initial guess run ahead in a child process (smoothing.initial_ahead).

Each check compares with the inline path computed independently in this process: the
fixed-lag smoother's own result, and the batch without the option.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.errors import PlanodomError
from planodom.geometry import transform_from_rpy_xyz
from planodom.smoothing import initial_ahead
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.synthetic import make_sequence
from planodom.smoothing.windowed import WindowedSmoother, smooth_windowed

pytestmark = pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork")


@pytest.fixture(scope="module")
def sequence():
    return make_sequence(
        30, seed=3, sigma_rotation=1e-3, sigma_translation=0.01, sigma_normal=2e-3,
        sigma_offset=0.01,
    )  # fmt: skip


def _config(concurrent: bool) -> PlanodomConfig:
    return PlanodomConfig().updated(
        {"smoothing.window": 5, "smoothing.batch_initial_concurrent": concurrent}
    )


def test_the_poses_are_the_fixed_lag_smoothers_bit_for_bit(sequence) -> None:
    cfg = _config(True).updated({"smoothing.compute_covariances": False})
    expected = smooth_windowed(sequence.planes, sequence.relatives, cfg).poses
    ahead = initial_ahead.GuessAhead(sequence.planes, sequence.relatives, cfg)
    first = [ahead[k] for k in range(len(sequence.planes))]  # as the graph asks, in order
    assert np.array_equal(ahead.finish(), expected)
    assert np.array_equal(np.stack(first), expected)
    assert ahead.child_cpu_s > 0.0


def test_a_first_pose_multiplies_each_pose_as_the_stack(sequence) -> None:
    cfg = _config(True).updated({"smoothing.compute_covariances": False})
    T = transform_from_rpy_xyz(0.01, -0.02, 0.7, 3.0, -4.0, 0.5)
    ahead = initial_ahead.GuessAhead(sequence.planes, sequence.relatives, cfg, T)
    got = np.stack([ahead[k] for k in range(len(sequence.planes))])
    assert np.array_equal(got, T @ ahead.finish())


def test_the_batch_is_the_inline_batch_bit_for_bit(sequence) -> None:
    inline = smooth_batch(sequence.planes, sequence.relatives, _config(False))
    ahead = smooth_batch(sequence.planes, sequence.relatives, _config(True))
    assert inline.covariances is not None and ahead.covariances is not None
    assert np.array_equal(ahead.initial_poses, inline.initial_poses)
    assert np.array_equal(ahead.poses, inline.poses)
    assert np.array_equal(ahead.covariances, inline.covariances, equal_nan=True)
    assert ahead.errors == inline.errors
    assert ahead.stats == inline.stats
    assert ahead.qr_fallback_epochs == inline.qr_fallback_epochs


def test_a_failure_in_the_child_is_raised_here(sequence, monkeypatch) -> None:
    original = WindowedSmoother.add_epoch

    def failing(self, planes, relatives=()):
        if self.n_epochs == 12:
            raise PlanodomError("fixed-lag smoother failed at epoch 12 (planted)")
        return original(self, planes, relatives)

    monkeypatch.setattr(WindowedSmoother, "add_epoch", failing)  # the fork inherits it
    with pytest.raises(PlanodomError, match="epoch 12 \\(planted\\)"):
        smooth_batch(sequence.planes, sequence.relatives, _config(True))


def test_without_fork_the_option_is_refused_by_name(sequence, monkeypatch) -> None:
    monkeypatch.delattr(os, "fork")
    with pytest.raises(PlanodomError, match="batch_initial_concurrent"):
        initial_ahead.GuessAhead(sequence.planes, sequence.relatives, _config(True))
