"""Pairwise consistency of loop hypotheses (planodom.smoothing.loop_gate.consistent_hypotheses)
on the synthetic closed loop of tests/smoothing/test_loop_closure.py, and the maximum-weight
clique it keeps against brute force."""

from __future__ import annotations

from dataclasses import replace
from itertools import combinations

import numpy as np
import pytest

from planodom.geometry import make_transform
from planodom.smoothing import loop_candidates
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.loop_gate import max_weight_clique
from planodom.smoothing.loop_records import loop_factor_counts
from tests.smoothing.test_loop_candidates import _candidates_only
from tests.smoothing.test_loop_closure import N_LAP, _end_error, _loop_problem


@pytest.fixture(scope="module")
def problem():
    return _loop_problem()


def test_max_weight_clique_is_the_heaviest_by_brute_force():
    rng = np.random.default_rng(3)
    for _ in range(40):
        n = int(rng.integers(1, 9))
        upper = np.triu(rng.random((n, n)) < rng.uniform(0.2, 0.9), 1)
        adjacent = upper | upper.T
        weights = rng.integers(1, 20, n).astype(float)
        best = 0.0
        for size in range(1, n + 1):
            for nodes in combinations(range(n), size):
                if all(adjacent[a, b] for a, b in combinations(nodes, 2)):
                    best = max(best, float(weights[list(nodes)].sum()))
        clique = max_weight_clique(adjacent, weights)
        assert all(adjacent[a, b] for a, b in combinations(clique, 2))
        assert weights[clique].sum() == pytest.approx(best)


def _aliased_before(epoch: int, shift_m: float):
    """``match_old_epoch`` whose loop poses before ``epoch`` are shifted ``shift_m`` along x
    (an aliased corridor: consistent with each other, they pass the confirmation)."""
    original = loop_candidates.CandidateLoopBuilder.match_old_epoch

    def aliased(self, k, e):
        rel = original(self, k, e)
        if rel is None or k >= epoch:
            return rel
        shift = make_transform(np.eye(3), [shift_m, 0.0, 0.0])
        return replace(rel, T_prev_curr=rel.T_prev_curr @ shift)

    return aliased


def test_an_aliased_hypothesis_before_the_right_one_is_refused(problem, monkeypatch):
    """The lap's first loop poses aliased 3 m along (one hypothesis of several factors),
    the later ones right (more factors): the two disagree by far more than the drift
    between their nearest factors, and "hypotheses" keeps the right one before the graph
    is optimised; every kept factor is within 3 sigma of the truth and the loop end is as
    with the right factors alone."""
    truth, planes, relatives = problem
    right = smooth_batch(planes, relatives, _candidates_only())
    first = min(f.epoch for f in right.loop_factors)
    assert first >= N_LAP - 10
    switch = first + 4
    monkeypatch.setattr(
        loop_candidates.CandidateLoopBuilder, "match_old_epoch", _aliased_before(switch, 3.0)
    )
    cfg = _candidates_only().updated({"smoothing.loop_consistency": "hypotheses"})
    res = smooth_batch(planes, relatives, cfg)
    wrong = [f for f in res.loop_factors if f.wrong(truth)]
    assert len(wrong) >= 2 and all(f.epoch < switch for f in wrong)
    assert all(f.removed and np.isnan(f.chi2) for f in wrong)  # refused before optimisation
    counts = loop_factor_counts(res.loop_factors, truth)
    assert counts["loop_factors_wrong_kept"] == 0 and counts["loop_factors"] >= 4
    assert _end_error(res.poses, truth) < 0.6 * _end_error(res.initial_poses, truth)
    assert _end_error(res.poses, truth) == pytest.approx(_end_error(right.poses, truth), abs=0.05)
