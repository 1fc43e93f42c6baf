"""``smoothing.loop_consistency_weight``: what a loop hypothesis weighs in the clique of
planodom.smoothing.loop_gate.consistent_hypotheses.

A corridor revisited three times against old epoch 0 (the truth: the loop poses place the
current epoch where the chained guess has it). One pass, 22 consecutive loop poses
(epochs 100-121), tied a cross wall to its neighbour 3.2 m along x: one aliased
observation repeated. Two later passes, 4 loop poses each (200-203, 300-303), are right.
Whether two hypotheses agree is decided by their corrections alone (the same shift within
0.5 m), not by their weights. By factors the aliased pass outweighs both right ones
(22 > 8); by revisits the two right passes outweigh it (2 > 1).
"""

from __future__ import annotations

from types import SimpleNamespace

import gtsam
import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.geometry import make_transform
from planodom.smoothing.loop_gate import consistent_hypotheses
from planodom.smoothing.loop_records import LoopFactor
from planodom.smoothing.loop_weights import clique_weights, revisits

ALIAS_M = 3.2
# (current epochs, hypothesis, shift along x of the loop pose, m)
PASSES = [(range(100, 122), 0, ALIAS_M), (range(200, 204), 1, 0.0), (range(300, 304), 2, 0.0)]


def _kept(weight: str, passes=PASSES) -> dict[int, bool]:
    """Hypothesis -> whether the clique kept it."""
    cfg = PlanodomConfig().updated(
        {"smoothing.loop_consistency": "hypotheses", "smoothing.loop_consistency_weight": weight}
    )
    factors, n = [], 0
    for epochs, group, shift in passes:
        for k in epochs:
            T = make_transform(np.eye(3), [shift, 0.0, 0.0])
            factors.append(LoopFactor(k, 0, T, np.diag([1e-6] * 3 + [4e-4] * 2), 3, n, group))
            n += 1
    builder = SimpleNamespace(
        config=cfg.smoothing,
        loop_factors=factors,
        poses={k: np.eye(4) for k in [0] + [k for e, _, _ in passes for k in e]},
        corrections_agree=lambda a, b: abs(a.W[0, 3] - b.W[0, 3]) < 0.5,
        stats=SimpleNamespace(reidentified_removed=0),
    )
    graph = gtsam.NonlinearFactorGraph()
    for _ in factors:
        graph.add(gtsam.PriorFactorPose3(0, gtsam.Pose3(), gtsam.noiseModel.Unit.Create(6)))
    consistent_hypotheses(builder, graph, {})
    return {g: not any(f.removed for f in factors if f.group == g) for _, g, _ in passes}


def test_by_factors_one_aliased_pass_outweighs_two_right_ones():
    assert _kept("factors") == {0: True, 1: False, 2: False}


def test_by_revisits_the_right_passes_are_kept_and_the_alias_removed():
    assert _kept("revisits") == {0: False, 1: True, 2: True}


def test_as_many_revisits_the_factors_decide():
    one_right = PASSES[:2]  # one aliased pass of 22 against one right pass of 4
    assert _kept("revisits", one_right) == _kept("factors", one_right) == {0: True, 1: False}


@pytest.mark.parametrize(
    ("epochs", "gap", "expected"),
    [([], 10, 0), ([5], 10, 1), ([3, 1, 2, 2], 1, 1), ([1, 12], 10, 2), ([1, 11], 10, 1)],
)
def test_revisits_are_runs_of_epochs_at_most_the_gap_apart(epochs, gap, expected):
    assert revisits(epochs, gap) == expected


def test_more_revisits_always_outweigh_more_factors():
    two = clique_weights("revisits", 10, [[1, 2, 3], [50], [80]], [3, 1, 900])
    assert two[0] + two[1] > two[2]  # two passes of 4 factors, one of 900 ties
    same = clique_weights("revisits", 10, [[1, 2, 3], [50], [80, 200]], [3, 1, 900])
    assert same[2] > same[0] + same[1]  # two passes each: the ties decide
    assert list(clique_weights("factors", 10, [[1], [2]], [3, 4])) == [3.0, 4.0]
