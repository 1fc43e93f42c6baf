"""``smoothing.loop_candidate_reference``: the map epoch the loop candidates' bounds grow the
drift from (W32D)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from planodom.odometry import Status
from planodom.smoothing import loop_candidates
from planodom.smoothing.loop_records import LoopMatch
from planodom.smoothing.loops import LoopClosingBuilder
from tests.smoothing.test_loop_candidates import _candidates_only, _step

WALLS = {  # landmark -> (last-seen epoch, world normal): x-walls at 1 and 6, a y-wall at 12
    1: (1, [1.0, 0.0, 0.0]),
    2: (6, [1.0, 0.0, 0.0]),
    3: (12, [0.0, 1.0, 0.0]),
}


def _builder(mode: str) -> loop_candidates.CandidateLoopBuilder:
    """20 epochs driven 0.3 m each along x, epochs 3-10 bridged (no step measured), the run's
    drift; three map walls."""
    cfg = _candidates_only().updated(
        {"smoothing.loop_candidate_drift": "run", "smoothing.loop_candidate_reference": mode}
    )
    builder = loop_candidates.CandidateLoopBuilder(cfg)
    for k in range(20):
        bridged = 3 <= k <= 10
        xy = (0.3 + 0.01 * (k % 3), 0.0)
        builder.add_epoch(
            [], [] if k == 0 else [_step(k, xy, Status.DEGENERATE if bridged else Status.OK)]
        )
    builder.landmarks = {
        j: SimpleNamespace(last_seen=(e, np.zeros(4)), plane_world=np.append(n, 0.0))
        for j, (e, n) in WALLS.items()
    }
    return builder


def _accept(builder: loop_candidates.CandidateLoopBuilder, k: int, monkeypatch) -> None:
    """A full-rank match at k tying the three walls, accepted as a new correction (the map's
    verification replaced: it takes (k, the earliest last sighting), as it does)."""

    def accept(self, match, T_world_curr, full):  # noqa: ANN001, ANN202
        self._reference = (match.epoch, min(self.landmarks[j].last_seen[0] for j, _ in match.ties))
        return "accepted"

    monkeypatch.setattr(LoopClosingBuilder, "_verify", accept)
    match = LoopMatch(k, 1, np.eye(4), np.eye(4), np.eye(5), np.zeros((3, 3)), np.nan,
                      [(j, 0) for j in WALLS])  # fmt: skip
    assert builder._verify(match, np.eye(4), True) == "accepted"


@pytest.mark.parametrize("mode, map_epoch", [("earliest", 1), ("spanning", 12)])
def test_the_reference_is_the_earliest_or_the_spanning_sighting(mode, map_epoch, monkeypatch):
    """The accepted correction's map epoch: the earliest last sighting of the tied walls
    (1), or the one by which they span two non-parallel normals (the y-wall's, 12)."""
    builder = _builder(mode)
    _accept(builder, 18, monkeypatch)
    assert builder._map_reference() == (18, map_epoch)
    assert builder._reference == (18, 1)  # the map's own verification keeps its own


def test_the_spanning_reference_grows_the_bound_over_the_bridged_stretch(monkeypatch):
    """With "spanning" the candidates' bound to old epoch 0 holds the drift from 0 to 12,
    bridged epochs 3-10 included: the same bound as a reference taken at 12, and wider than
    the earliest's (0 to 1, measured)."""
    earliest, spanning = _builder("earliest"), _builder("spanning")
    for builder in (earliest, spanning):
        _accept(builder, 18, monkeypatch)
    old = np.array([0])
    wide = spanning._bounds(19, old)[0][0]
    narrow = earliest._bounds(19, old)[0][0]
    earliest._reference = (18, 12)  # the earliest mode with its reference moved by hand
    assert wide == pytest.approx(earliest._bounds(19, old)[0][0])
    assert wide > 1.5 * narrow
