"""Pairwise consistency of loop hypotheses (planodom.smoothing.loop_gate.consistent_hypotheses)
on the synthetic closed loop of tests/smoothing/test_loop_closure.py, and the maximum-weight
clique it keeps against brute force."""

from __future__ import annotations

from dataclasses import replace
from itertools import combinations

import gtsam
import numpy as np
import pytest

from planodom.geometry import invert_transform, make_transform
from planodom.odometry import RelativePose, Status
from planodom.smoothing import loop_candidates
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.graph import X
from planodom.smoothing.loop_gate import (
    consistent_hypotheses,
    gate_loop_factors,
    max_weight_clique,
)
from planodom.smoothing.loop_records import (
    Correction,
    LoopFactor,
    LoopMatch,
    Reidentification,
    loop_factor_counts,
)
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


def _corridor_builder(
    truth: np.ndarray, consistency: str = "hypotheses"
) -> loop_candidates.CandidateLoopBuilder:
    """A builder that has chained the steps of ``truth`` (each 2 mm long and 0.01 deg off:
    a drifting odometry) with measured 5-DoF covariances, and no planes."""
    cfg = _candidates_only().updated({"smoothing.loop_consistency": consistency})
    builder = loop_candidates.CandidateLoopBuilder(cfg)
    bias = make_transform(
        np.array([[np.cos(2e-4), -np.sin(2e-4), 0], [np.sin(2e-4), np.cos(2e-4), 0], [0, 0, 1]]),
        [0.002, 0.0, 0.0],
    )
    cov = np.diag([1e-6, 1e-6, 1e-6, 1e-5, 1e-5])
    for k in range(len(truth)):
        step = [] if k == 0 else [invert_transform(truth[k - 1]) @ truth[k] @ bias]
        builder.add_epoch([], [RelativePose(T, cov, Status.OK, prev=k - 1, curr=k) for T in step])
    return builder


def test_an_aliased_corridor_hypothesis_interleaved_with_the_right_one_is_refused():
    """A corridor along x driven out and back (0.18 m per epoch), its end revisited: loop
    factors to epoch 0 aliased 4.6 m along the corridor (one cross wall mistaken for the
    next: consistent with each other, three hypotheses, 18 factors) interleaved with right
    ones (two hypotheses, 27 factors), as on 2D-rig world 16 at 2 cm. Each pair of nearest
    factors of an aliased and a right hypothesis disagrees far beyond the drift of the few
    epochs between them: the aliased ones are removed, the right ones kept (by the truth)."""
    truth = _out_and_back()
    builder = _corridor_builder(truth)
    plan = [(range(80, 84), True), (range(86, 98), True), (range(98, 102), False),
            (range(102, 104), True), (range(104, 121), False)]  # fmt: skip
    graph = gtsam.NonlinearFactorGraph()
    _add_loop_factors(builder, graph, truth, plan)
    assert sum(f.wrong(truth) for f in builder.loop_factors) == 18
    removed = consistent_hypotheses(builder, graph, {})
    assert removed == 18
    for f in builder.loop_factors:
        assert f.removed is f.wrong(truth)
        assert (graph.at(f.factor) is None) is f.removed


@pytest.mark.parametrize("removes", ["hypothesis", "factor"])
def test_the_gate_removes_a_failing_factor_with_its_hypothesis_or_alone(removes):
    """Three loop factors of one hypothesis, priors on X(0) at 0, 0 and 100 m from the value
    (unit noise: chi2 0, 0 and 1e4 against chi2(5)'s 0.999 quantile, 20.5)."""
    cfg = _candidates_only().updated({"smoothing.loop_gate_removes": removes})
    builder = loop_candidates.CandidateLoopBuilder(cfg)
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    values.insert(X(0), gtsam.Pose3())
    for i, x in enumerate((0.0, 0.0, 100.0)):
        prior = gtsam.Pose3(gtsam.Rot3(), np.array([x, 0.0, 0.0]))
        graph.add(gtsam.PriorFactorPose3(X(0), prior, gtsam.noiseModel.Unit.Create(6)))
        builder.loop_factors.append(LoopFactor(i + 1, 0, np.eye(4), np.eye(5), 3, i, 0))
    assert gate_loop_factors(builder, graph, {}, values) == (3 if removes == "hypothesis" else 1)
    np.testing.assert_allclose([f.chi2 for f in builder.loop_factors], [0.0, 0.0, 1e4])
    assert [f.removed for f in builder.loop_factors] == [removes == "hypothesis"] * 2 + [True]


def _corridor_with_map(
    map_shift_m: float, map_epochs: range, plan: list[tuple[range, bool]], consistency: str
):
    """The out-and-back corridor of the test above with loop factors to epoch 0 (``plan``:
    epochs and whether aliased 4.6 m along, one hypothesis each) and one map hypothesis:
    accepted full-rank matches at ``map_epochs``, each placing epoch k against its walls
    last seen at epoch 0 (shifted ``map_shift_m`` along the corridor), with three plane
    ties each. Returns the truth, builder, graph and the number of factors removed."""
    truth = _out_and_back()
    builder = _corridor_builder(truth, consistency)
    graph = gtsam.NonlinearFactorGraph()
    _add_loop_factors(builder, graph, truth, plan)
    cov, unit = LOOP_COV, gtsam.noiseModel.Unit.Create(6)
    shift = make_transform(np.eye(3), [map_shift_m, 0.0, 0.0])
    for k in map_epochs:
        T_world_curr = builder.poses[0] @ shift @ invert_transform(truth[0]) @ truth[k]
        T_world_pred = builder.poses[k]
        T_pred_curr = invert_transform(T_world_pred) @ T_world_curr
        ties = [(100 + i, i) for i in range(3)]
        builder.matches.append(
            LoopMatch(k, 0, T_world_pred, T_pred_curr, cov, np.zeros((3, 3)), 0.0, ties,
                      seen=0, full=True)
        )  # fmt: skip
        for j, i in ties:
            builder.reidentifications.append(Reidentification(k, i, j, graph.size()))
            graph.add(gtsam.PriorFactorPose3(X(k), gtsam.Pose3(), unit))
    return truth, builder, graph, consistent_hypotheses(builder, graph, {})


def test_map_ties_outweigh_an_aliased_majority_of_loop_factors():
    """Loop factors aliased 4.6 m along the corridor (two hypotheses, 23 factors) outnumber
    the right ones (4): "hypotheses" keeps the aliased ones; "hypotheses_and_map" weighs the
    map's 60 right ties too (they imply the true correction) and keeps the right loop
    factors and every tie, removing the aliased ones (by the truth)."""
    plan = [(range(80, 92), True), (range(95, 106), True), (range(110, 114), False)]
    truth, builder, graph, removed = _corridor_with_map(0.0, range(100, 120), plan, "hypotheses")
    assert removed == 4 and all(f.removed is not f.wrong(truth) for f in builder.loop_factors)
    truth, builder, graph, removed = _corridor_with_map(
        0.0, range(100, 120), plan, "hypotheses_and_map"
    )
    assert sum(f.wrong(truth) for f in builder.loop_factors) == 23
    assert removed == 23
    for f in builder.loop_factors:
        assert f.removed is f.wrong(truth)
        assert (graph.at(f.factor) is None) is f.removed
    assert not any(r.removed for r in builder.reidentifications)
    assert builder.stats.reidentified_removed == 0


def test_an_aliased_map_hypothesis_outweighed_by_loop_factors_loses_its_ties():
    """The map's matches placed 4.6 m along the corridor with few ties (two matches, six
    ties) against 27 right loop factors: the map hypothesis is left out of the clique and
    its ties are removed from the graph; no loop factor is."""
    plan = [(range(80, 94), False), (range(96, 109), False)]
    truth, builder, graph, removed = _corridor_with_map(
        4.6, range(100, 102), plan, "hypotheses_and_map"
    )
    assert sum(f.wrong(truth) for f in builder.loop_factors) == 0
    assert removed == 6 and not any(f.removed for f in builder.loop_factors)
    assert all(r.removed and graph.at(r.factor) is None for r in builder.reidentifications)
    assert builder.stats.reidentified_removed == 6


LOOP_COV = np.diag([1e-6, 1e-6, 1e-6, 0.015**2, 0.004**2])  # a loop factor's (5, 5)


def _out_and_back() -> np.ndarray:
    """(121, 4, 4) true poses: 60 steps of 0.18 m along a corridor and back, swaying."""
    n_out = 60
    x = np.concatenate([np.arange(n_out) * 0.18, (n_out - np.arange(n_out + 1)) * 0.18])
    return np.stack([make_transform(np.eye(3), [v, 0.02 * np.sin(k / 7), 0.0])
                     for k, v in enumerate(x)])  # fmt: skip


def _add_loop_factors(builder, graph, truth, plan) -> None:
    """Loop factors to epoch 0 from the truth (``plan``: epochs and whether aliased 4.6 m
    along the corridor, one hypothesis each), each with a unit prior in ``graph``."""
    for group, (epochs, aliased) in enumerate(plan):
        for k in epochs:
            T = invert_transform(truth[0]) @ truth[k]
            if aliased:
                T = make_transform(np.eye(3), [4.6, 0.0, 0.0]) @ T
            builder.loop_factors.append(LoopFactor(k, 0, T, LOOP_COV, 3, graph.size(), group))
            graph.add(gtsam.PriorFactorPose3(X(k), gtsam.Pose3(), gtsam.noiseModel.Unit.Create(6)))


def _drifted_map(map_epoch: str):
    """World 32's case: the out-and-back corridor chained by an odometry that measures
    every step but those of epochs 20-39 (0.5 m standard deviation per axis, each 0.15 m
    too long: the chained guess's late part lies 3 m from its early part), right loop
    factors of epochs 100-103 to epoch 0 (one hypothesis, 4 factors), and the map's
    accepted matches at epochs 95-114 (20 matches, 60 ties) placing each epoch where the
    chained guess has it: the late walls (last seen 5 epochs before) place it, one early
    wall (last seen at epoch 10) only along its own normal. Returns the truth, builder and
    number of factors removed by the clique."""
    truth = _out_and_back()
    cfg = _candidates_only().updated(
        {"smoothing.loop_consistency": "hypotheses_and_map", "smoothing.loop_map_epoch": map_epoch}
    )
    builder = loop_candidates.CandidateLoopBuilder(cfg)
    measured, unmeasured = np.diag([1e-6] * 3 + [1e-5] * 2), np.diag([1e-6] * 3 + [0.25] * 2)
    for k in range(len(truth)):
        steps = []
        if k:
            step = invert_transform(truth[k - 1]) @ truth[k]
            drifting = 20 <= k < 40
            if drifting:
                step = step @ make_transform(np.eye(3), [0.15, 0.0, 0.0])
            cov = unmeasured if drifting else measured
            steps = [RelativePose(step, cov, Status.OK, prev=k - 1, curr=k)]
        builder.add_epoch([], steps)
    graph = gtsam.NonlinearFactorGraph()
    _add_loop_factors(builder, graph, truth, [(range(100, 104), False)])
    unit = gtsam.noiseModel.Unit.Create(6)
    for k in range(95, 115):
        ties = [(100 + i, i) for i in range(3)]
        builder.matches.append(
            LoopMatch(k, 10, builder.poses[k], np.eye(4), LOOP_COV, np.zeros((3, 3)), 0.0, ties,
                      seen=10, full=True, spanning=k - 5)
        )  # fmt: skip
        for j, i in ties:
            builder.reidentifications.append(Reidentification(k, i, j, graph.size()))
            graph.add(gtsam.PriorFactorPose3(X(k), gtsam.Pose3(), unit))
    return truth, builder, consistent_hypotheses(builder, graph, {})


def test_a_map_match_is_compared_where_its_walls_place_it():
    """The right loop factors disagree with the map's matches by the 3 m of drift: against
    the early wall's sighting ("earliest") that drift is not allowed, and the map's 60 ties
    outvote the 4 factors; against the sighting that places the matches in full
    ("spanning", after the drifting stretch) it is, and both are kept (by the truth)."""
    truth, builder, removed = _drifted_map("earliest")
    drift = invert_transform(builder.poses[100]) @ builder.poses[0] @ invert_transform(truth[0])
    assert np.linalg.norm((drift @ truth[100])[:2, 3]) == pytest.approx(3.0, abs=0.05)
    assert not any(f.wrong(truth) for f in builder.loop_factors)
    assert removed == 4 and all(f.removed for f in builder.loop_factors)
    truth, builder, removed = _drifted_map("spanning")
    assert removed == 0 and not any(f.removed for f in builder.loop_factors)
    assert not any(r.removed for r in builder.reidentifications)


def test_a_match_without_a_spanning_sighting_is_compared_at_its_earliest():
    """Correction.of_match: "spanning" uses the match's ``spanning`` when noted, else
    its ``seen``; the correction itself is the same (epoch k where the map places it)."""
    T_pred = make_transform(np.eye(3), [1.0, 2.0, 0.0])
    poses = {7: make_transform(np.eye(3), [0.5, 0.0, 0.0])}
    match = LoopMatch(7, 3, T_pred, np.eye(4), LOOP_COV, np.zeros((3, 3)), 0.0, [], seen=3)
    assert Correction.of_match(match, poses, spanning=True).old == 3
    noted = Correction.of_match(replace(match, spanning=5), poses, spanning=True)
    assert noted.old == 5 and Correction.of_match(replace(match, spanning=5), poses).old == 3
    np.testing.assert_allclose(noted.W[:2, 3], [0.5, 2.0])
