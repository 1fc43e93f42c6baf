"""``smoothing.loop_map_parts``: the map's node in the clique of
planodom.smoothing.loop_gate.consistent_hypotheses split at each new correction.

A lap against old epoch 0 (the truth: every right correction leaves the chained guess
where it is). The map takes a right correction at epoch 100 (full-rank matches 100-110,
5 ties each, 55), then confirms a wrong one at epoch 200 (a wall spacing, 3.4 m
along x; matches 200-210, 4 ties each, 44) and tracks it. A right loop hypothesis
(6 loop factors, epochs 300-305 against epoch 0) is compared with the map through the
match of least drift (here: nearest in epochs), one of the wrong part's. Whether two
corrections agree is decided by their shift alone (within 0.5 m). As one node the map
(99 ties) disagrees with the loop and outweighs it: the right closure is removed. Split,
the right part (55) agrees with the loop (6) and outweighs the wrong part (44): the
closure and the right ties are kept, the wrong ties removed.
"""

from __future__ import annotations

from types import SimpleNamespace

import gtsam
import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.geometry import make_transform
from planodom.smoothing.loop_gate import consistent_hypotheses
from planodom.smoothing.loop_map_parts import split_at_corrections
from planodom.smoothing.loop_records import LoopFactor, LoopMatch, Reidentification

ALIAS_M = 3.4
COV5 = np.diag([1e-6] * 3 + [4e-4] * 2)


def _match(k: int, shift: float, mahalanobis: float) -> LoopMatch:
    T = make_transform(np.eye(3), [shift, 0.0, 0.0])
    return LoopMatch(k, 0, T, np.eye(4), COV5, np.zeros((3, 3)), mahalanobis, [], seen=0, full=True)


def _lap() -> tuple[list[LoopFactor], list[LoopMatch], list[Reidentification]]:
    """Loop factors, the map's accepted matches and its ties (factor indices after the
    loop factors'), as in the module docstring."""
    factors = [LoopFactor(k, 0, np.eye(4), COV5, 3, n, 0) for n, k in enumerate(range(300, 306))]
    matches = [_match(100, 0.0, np.nan)] + [_match(k, 0.0, 1.0) for k in range(101, 111)]
    matches += [_match(200, ALIAS_M, 100.0)] + [_match(k, ALIAS_M, 1.0) for k in range(201, 211)]
    epochs = [k for k in range(100, 111) for _ in range(5)]  # 5 walls tied per match
    epochs += [k for k in range(200, 211) for _ in range(4)]
    ties = [Reidentification(k, 0, 0, len(factors) + n) for n, k in enumerate(epochs)]
    return factors, matches, ties


def _run(parts: str) -> tuple[bool, int, int]:
    """(the loop closure kept, right ties removed, wrong ties removed)."""
    cfg = PlanodomConfig().updated({"smoothing.loop_map_parts": parts})
    factors, matches, ties = _lap()
    builder = SimpleNamespace(
        config=cfg.smoothing,
        loop_factors=factors,
        matches=matches,
        reidentifications=ties,
        poses={k: np.eye(4) for k in range(400)},
        corrections_agree=lambda a, b: abs(a.W[0, 3] - b.W[0, 3]) < 0.5,
        _candidate_drift=lambda spans: np.eye(3) * sum(abs(a - b) for a, b in spans),
        stats=SimpleNamespace(reidentified_removed=0),
    )
    graph = gtsam.NonlinearFactorGraph()
    for _ in range(len(factors) + len(ties)):
        graph.add(gtsam.PriorFactorPose3(0, gtsam.Pose3(), gtsam.noiseModel.Unit.Create(6)))
    consistent_hypotheses(builder, graph, {})
    right = sum(r.removed for r in ties if r.epoch < 200)
    wrong = sum(r.removed for r in ties if r.epoch >= 200)
    return not any(f.removed for f in factors), right, wrong


def test_as_one_node_the_wrong_part_removes_the_right_closure():
    assert _run("one") == (False, 0, 0)


def test_split_the_right_closure_and_part_are_kept_the_wrong_part_removed():
    assert _run("corrections") == (True, 0, 44)


def test_parts_start_at_each_new_correction():
    _, matches, ties = _lap()
    parts = split_at_corrections(matches, ties, 0.999)
    assert [(p[0][0].epoch, len(p[0]), p[1][0].epoch, len(p[1])) for p in parts] == [
        (100, 11, 100, 55),
        (200, 11, 200, 44),
    ]


def test_a_bad_value_names_the_key():
    with pytest.raises(Exception, match="loop_map_parts"):
        PlanodomConfig().updated({"smoothing.loop_map_parts": "two"})


def test_matches_a_part_per_accepted_full_rank_match():
    _, matches, ties = _lap()
    parts = split_at_corrections(matches, ties, 0.999, every=True)
    assert [p[0][0].epoch for p in parts] == list(range(100, 111)) + list(range(200, 211))
    assert [len(p[1]) for p in parts] == [5] * 11 + [4] * 11
