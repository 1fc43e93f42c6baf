"""``smoothing.loop_candidate_confirm_old``: verified loop poses confirm each other into
one hypothesis only when their old epochs are near too (planodom.smoothing.loop_candidates).

The builder's matching is replaced by a script of verified loop poses that all agree
(the drift between two old epochs far apart lets them): (current, old) = (100, 0),
(102, 0), (104, 378), (106, 0), (108, 0).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.odometry.relative import RelativePose
from planodom.smoothing.loop_candidates import CandidateLoopBuilder

SCRIPT = [(100, 0), (102, 0), (104, 378), (106, 0), (108, 0)]


def _factors(confirm_old: bool) -> list[tuple[int, int, int]]:
    """(current, old, hypothesis) of the loop factors the script makes."""
    cfg = PlanodomConfig().updated({"smoothing.loop_candidate_confirm_old": confirm_old})
    b = CandidateLoopBuilder.__new__(CandidateLoopBuilder)  # the decision only, no graph
    b.config, b._aliased, b._last_verified, b._group = cfg.smoothing, -1, None, -1
    b.loop_factors, b.candidate_attempts = [], 0
    old = dict(SCRIPT)
    b.old_epoch_candidates = lambda k: [old[k]]
    b.match_old_epoch = lambda k, e: RelativePose(np.eye(4), np.eye(5), prev=e, curr=k)
    b._agrees_with_map = b._plausible = lambda rel: True
    b._agrees = lambda first, second: True

    def add(update, rel):
        b.loop_factors.append(SimpleNamespace(epoch=rel.curr, old=rel.prev, group=b._group))

    b._add_loop_factor = add
    for k, _ in SCRIPT:
        b._close_to_old_epoch(SimpleNamespace(epoch=k))
    return [(f.epoch, f.old, f.group) for f in b.loop_factors]


@pytest.mark.parametrize(
    ("confirm_old", "expected"),
    [
        (False, [(100, 0, 0), (102, 0, 0), (104, 378, 0), (106, 0, 0), (108, 0, 0)]),
        (True, [(100, 0, 0), (102, 0, 0), (106, 0, 1), (108, 0, 1)]),
    ],
)
def test_a_far_old_epoch_confirms_nothing(confirm_old, expected):
    assert _factors(confirm_old) == expected
