"""Loop-candidate factors (planodom.smoothing.loop_candidates) on the synthetic closed loop
of tests/smoothing/test_loop_closure.py: a drifted chain whose lap end revisits its start."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.geometry import invert_transform, make_transform, pose5_from_transform
from planodom.smoothing import loop_candidates
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.loop_records import LoopFactor, loop_factor_counts
from tests.smoothing.test_loop_closure import N_LAP, _config, _end_error, _loop_problem


@pytest.fixture(scope="module")
def problem():
    return _loop_problem()


def _candidates_only(on: bool = True) -> PlanodomConfig:
    """Loop closure by old-epoch candidates alone: no map match has enough planes."""
    return _config(True).updated(
        {"smoothing.loop_min_matches": 1000, "smoothing.loop_candidates": on}
    )


def test_loop_candidates_alone_close_the_loop(problem):
    truth, planes, relatives = problem
    without = smooth_batch(planes, relatives, _candidates_only(False))
    res = smooth_batch(planes, relatives, _candidates_only())
    assert not without.loop_factors and not res.reidentifications
    kept = [f for f in res.loop_factors if not f.removed]
    assert len(kept) >= 2
    for f in kept:  # each measures the true relative pose of a revisit, within 3 sigma
        assert f.epoch - f.old >= 20
        true = invert_transform(truth[f.old]) @ truth[f.epoch]
        err = pose5_from_transform(invert_transform(true) @ f.T_old_curr)
        assert np.linalg.norm(err[3:]) < 0.3 and abs(err[2]) < np.radians(2.0)
        assert not f.wrong(truth)
    assert _end_error(res.initial_poses, truth) > 1.5  # the drift the loop must close
    assert _end_error(without.poses, truth) > 0.4
    assert _end_error(res.poses, truth) < 0.6 * _end_error(without.poses, truth)


def test_planted_wrong_loop_poses_are_refused_or_removed(problem, monkeypatch):
    """Loop poses shifted 3 m at every candidate after the lap (consistent with each
    other, so they pass the confirmation). With the map, they disagree with its accepted
    correction and tie nothing; without it (candidates alone), the gate removes them and
    the result is that of no loop closure."""
    truth, planes, relatives = problem
    original = loop_candidates.CandidateLoopBuilder.match_old_epoch

    def shifted(self, k, e):
        rel = original(self, k, e)
        if rel is None:
            return None
        return replace(rel, T_prev_curr=rel.T_prev_curr @ make_transform(np.eye(3), [3.0, 0, 0]))

    plain = smooth_batch(planes, relatives, _candidates_only(False))
    monkeypatch.setattr(loop_candidates.CandidateLoopBuilder, "match_old_epoch", shifted)
    with_map = smooth_batch(planes, relatives, _config(True))
    assert not with_map.loop_factors
    assert _end_error(with_map.poses, truth) < 0.3  # the map still closes the loop
    alone = smooth_batch(planes, relatives, _candidates_only())
    assert alone.loop_factors  # the shifted poses were verified and confirmed
    counts = loop_factor_counts(alone.loop_factors, truth)
    assert counts["loop_factors_wrong_kept"] == 0
    assert counts["loop_factors_wrong_removed"] == len(alone.loop_factors)
    np.testing.assert_allclose(alone.poses[-1], plain.poses[-1], atol=0.05)


def test_old_epoch_candidates_follow_the_rule(problem, monkeypatch):
    """Every candidate is at least the minimum gap old and within the radius plus its
    translation bound; every epoch left out that satisfies it is farther than the last."""
    truth, planes, relatives = problem
    seen = []
    original = loop_candidates.CandidateLoopBuilder.old_epoch_candidates

    def checked(self, k):
        out = original(self, k)
        c = self.config
        position = self._predicted(k)[:2, 3]
        old = np.arange(max(k - c.loop_min_gap_epochs + 1, 0))
        dist = np.array([np.linalg.norm(self.poses[e][:2, 3] - position) for e in old])
        bound = self._bounds(k, old)[0] if len(old) else np.zeros(0)
        ok = dist <= c.loop_candidate_radius_m + bound
        assert all(e <= k - c.loop_min_gap_epochs and ok[e] for e in out)
        if 0 < len(out) < c.loop_candidate_max:
            assert all(dist[e] >= dist[out[-1]] - 1e-9 for e in np.flatnonzero(ok) if e not in out)
        seen.append(len(out))
        return out

    monkeypatch.setattr(loop_candidates.CandidateLoopBuilder, "old_epoch_candidates", checked)
    smooth_batch(planes, relatives, _candidates_only())
    assert max(seen) > 0 and seen[: N_LAP // 4] == [0] * (N_LAP // 4)


def test_a_loop_factor_is_wrong_beyond_three_sigma():
    """LoopFactor.wrong against true poses built to put the error at 2 and 4 sigma."""
    gt = np.stack([np.eye(4), make_transform(np.eye(3), [5.0, 1.0, 0.0])])
    cov = np.diag([1e-6, 1e-6, 1e-6, 0.01, 0.01])  # 10 cm in x and y
    for shift, wrong in ((0.2, False), (0.4, True)):
        T = make_transform(np.eye(3), [5.0 + shift, 1.0, 0.3])  # z is not measured
        f = LoopFactor(1, 0, T, cov, 3, 0)
        # the factor error is the true (predicted) minus the measured translation
        np.testing.assert_allclose(f.truth_error(gt), [0, 0, 0, -shift, 0], atol=1e-12)
        assert f.wrong(gt) is wrong
