"""``smoothing.loop_consistency_pair``: the pair of factors through which the clique
compares two loop hypotheses (planodom.smoothing.loop_gate.consistent_hypotheses).

Two hypotheses of two factors each, to old epoch 0: one factor of each with a sigma of
6 m along x (a pose placed by one wall across a corridor), one with 2 cm. The nearest in
epochs are 110 and 112 (6 m and 6 m); the sharpest pair, under the same drift, is the two
factors of 2 cm (100 and 130).
"""

from __future__ import annotations

from types import SimpleNamespace

import gtsam
import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.smoothing.loop_gate import consistent_hypotheses
from planodom.smoothing.loop_records import LoopFactor

# (current epoch, hypothesis, sigma along x, m)
FACTORS = [(100, 0, 0.02), (110, 0, 6.0), (112, 1, 6.0), (130, 1, 0.02)]


def _compared(pair: str) -> list[tuple[int, int]]:
    """The (current epoch, current epoch) pairs the clique compared."""
    cfg = PlanodomConfig().updated(
        {"smoothing.loop_consistency": "hypotheses", "smoothing.loop_consistency_pair": pair}
    )
    compared: list[tuple[int, int]] = []
    factors = []
    for n, (k, group, sigma) in enumerate(FACTORS):
        cov = np.diag([1e-6, 1e-6, 1e-6, sigma**2, 1e-4])
        factors.append(LoopFactor(k, 0, np.eye(4), cov, 3, n, group))
    builder = SimpleNamespace(
        config=cfg.smoothing,
        loop_factors=factors,
        poses={k: np.eye(4) for k in (0, 100, 110, 112, 130)},
        _candidate_drift=lambda spans: np.diag([1e-6, 0.01, 0.01]),
        corrections_agree=lambda a, b: compared.append((a.epoch, b.epoch)) or True,
        stats=SimpleNamespace(reidentified_removed=0),
    )
    assert consistent_hypotheses(builder, gtsam.NonlinearFactorGraph(), {}) == 0
    return compared


@pytest.mark.parametrize(("pair", "expected"), [("nearest", (110, 112)), ("sharpest", (100, 130))])
def test_two_hypotheses_are_compared_through_the_pair_asked_for(pair, expected):
    assert _compared(pair) == [expected]
