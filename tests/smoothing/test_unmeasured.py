"""The deskewing error of epochs no step into was measured (planodom.smoothing.unmeasured)
against its closed form from known constant twists, and where the batch's covariances
take it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from planodom.config import PlanodomConfig, SmoothingConfig
from planodom.errors import ConfigError
from planodom.odometry.relative import RelativePose, Status
from planodom.se3 import se3_exp
from planodom.smoothing.batch_covariances import sandwich_inputs
from planodom.smoothing.unmeasured import span_ratio, unmeasured_errors, with_unmeasured

DT = 0.2  # s between epochs


def _steps(
    twists: np.ndarray, bridged: set[int], times: tuple[float, float] | None = (0.0, 0.15)
) -> list[RelativePose]:
    """delta = 1 steps of constant twists (E - 1, 6) per DT into epochs 1..E-1; those in
    ``bridged`` unresolved (the held velocity, the smoothing's bridge: no point times),
    the others measured and deskewed with their twist, points over ``times``."""
    out = []
    for k, w in enumerate(twists, start=1):
        if k in bridged:
            out.append(RelativePose(se3_exp(w * DT), None, status=Status.UNRESOLVED, prev=k - 1,
                                    curr=k, time_spread=True, interval_s=float("nan")))  # fmt: skip
        else:
            out.append(RelativePose(se3_exp(w * DT), None, prev=k - 1, curr=k, time_spread=True,
                                    deskew_twist=w, deskew_times=times, interval_s=DT))  # fmt: skip
    return out


def test_errors_are_the_motion_over_the_points() -> None:
    """For a constant twist ``w`` the motion over points spread over ``[0, s]`` is ``s w``
    (closed form): a bridged epoch's ``d_k`` is minus that, with ``s / dt`` the run's
    median where the bridge does not carry its own point times."""
    rng = np.random.default_rng(0)
    twists = rng.normal(0.0, 0.5, (8, 6))
    rels = _steps(twists, {3, 4, 7})
    assert span_ratio(rels) == 0.15 / DT
    d = unmeasured_errors(rels, 9)
    for k in (3, 4, 7):
        np.testing.assert_allclose(d[k], -0.15 * twists[k - 1], atol=1e-12)
    assert np.all(np.isnan(d[[0, 1, 2, 5, 6, 8]]))  # measured, first, or no step into it
    # a bridge that carries its own points' times (deskewed with a predicted twist) uses them
    times = {"deskew_twist": twists[3], "deskew_times": (-0.05, 0.1), "interval_s": DT}
    own = [replace(r, **times) if r.curr == 4 else r for r in rels]
    np.testing.assert_allclose(unmeasured_errors(own, 9)[4], -0.1 * twists[3], atol=1e-12)
    # without any step carrying times the points span the whole interval
    bare = [replace(r, deskew_times=None) for r in rels]
    np.testing.assert_allclose(unmeasured_errors(bare, 9)[3], -DT * twists[2], atol=1e-12)


def test_measured_instant_and_undeskewed_epochs_are_left_alone() -> None:
    twists = np.random.default_rng(1).normal(0.0, 0.5, (6, 6))
    rels = _steps(twists, {2, 5})
    # a measured step into epoch 2 besides its bridge (delta 1): the epoch was measured
    twin = RelativePose(se3_exp(twists[1] * DT), None, prev=1, curr=2, time_spread=True,
                        deskew_twist=twists[1], deskew_times=(0.0, 0.15),
                        interval_s=DT)  # fmt: skip
    assert np.all(np.isnan(unmeasured_errors([twin, *rels], 7)[2]))
    # taken at one instant: nothing to deskew
    instant = [replace(r, time_spread=False) if r.curr == 5 else r for r in rels]
    assert np.all(np.isnan(unmeasured_errors(instant, 7)[5]))
    # measured but kept without deskewing: sandwich_undeskewed's, not counted twice
    kept = [replace(r, deskew_twist=None) if r.curr == 4 else r for r in rels]
    assert np.all(np.isnan(unmeasured_errors(kept, 7)[4]))


def test_with_unmeasured_adds_the_squared_motion_on_those_epochs_only() -> None:
    twists = np.random.default_rng(2).normal(0.0, 0.5, (5, 6))
    rels = _steps(twists, {3})
    Q = np.stack([np.diag(np.full(6, 1e-6 * (k + 1))) for k in range(6)])
    out = with_unmeasured(Q, rels)
    d = -0.15 * twists[2]
    np.testing.assert_allclose(out[3], Q[3] + np.diag(d**2), atol=1e-15)
    assert np.array_equal(np.delete(out, 3, axis=0), np.delete(Q, 3, axis=0))
    assert with_unmeasured(Q, _steps(twists, set())) is Q


def test_sandwich_inputs_take_it_only_when_asked() -> None:
    """With "motion" the sandwich adds the bridged epoch's squared motion to its
    ``Q_k``; "change" (the default) leaves ``Q`` as before; "fitted" reads neither."""
    twists = np.random.default_rng(3).normal(0.0, 0.5, (9, 6))
    rels = _steps(twists, {5})
    on, _ = sandwich_inputs(
        SmoothingConfig(covariance_model="sandwich", sandwich_unmeasured="motion"), {}, rels, 10
    )
    off, _ = sandwich_inputs(SmoothingConfig(covariance_model="sandwich"), {}, rels, 10)
    assert SmoothingConfig().sandwich_unmeasured == "change"
    assert on is not None and off is not None
    np.testing.assert_allclose(on[5] - off[5], np.diag((0.15 * twists[4]) ** 2), atol=1e-15)
    assert np.array_equal(np.delete(on, 5, axis=0), np.delete(off, 5, axis=0))
    fitted = SmoothingConfig(covariance_model="fitted", sandwich_unmeasured="motion")
    assert sandwich_inputs(fitted, {}, rels, 10) == (None, None)


def test_a_bad_value_is_refused():
    with pytest.raises(ConfigError, match="sandwich_unmeasured"):
        PlanodomConfig().updated({"smoothing.sandwich_unmeasured": "yes"})
