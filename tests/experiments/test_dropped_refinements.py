"""experiments/dropped_refinements.py: its conditions and totals, by construction."""

from __future__ import annotations

import pytest
from experiment_scripts import EXPERIMENTS, load_script

from planodom.odometry.relative import Status


@pytest.fixture
def script(monkeypatch):
    monkeypatch.syspath_prepend(str(EXPERIMENTS))  # it imports builtin_scenes beside it
    return load_script("dropped_refinements")


def _row(source, again, ref, same_ref=True, to=Status.DEGENERATE, errors=(0.2, 0.1)):
    """A recorded refinement: (planes, distinct surfaces) of each, rotation errors (deg)."""
    return {"world": 0, "epoch": 1, "from": Status.OK, "to": to, "same_ref": same_ref,
            "source": source, "again": again, "ref": ref,
            "source_err": (errors[0], 1.0), "again_err": (errors[1], 1.0)}  # fmt: skip


def test_split_conditions_are_fewer_fragments_against_a_split_reference(script) -> None:
    conditions = script.conditions
    assert conditions(_row((13, 4), (6, 6), (5, 3)))  # world 166's epoch 74
    assert not conditions(_row((6, 6), (6, 6), (5, 3)))  # nothing merged
    assert not conditions(_row((13, 4), (8, 4), (5, 5)))  # the reference whole
    assert not conditions(_row((13, 4), (13, 4), (5, 3)))  # as many fragments


def test_the_totals_count_only_ok_steps_turned_degenerate_against_the_same_reference(
    script,
) -> None:
    summary = script.summary
    rows = [
        _row((13, 4), (6, 6), (5, 3), errors=(0.3, 0.1)),  # closer, with the conditions
        _row((6, 6), (6, 6), (5, 5), errors=(0.1, 0.5)),  # farther
        _row((6, 6), (6, 6), (5, 5), same_ref=False),  # kept: the reference extracted again
        _row((6, 6), (6, 6), (5, 5), to=Status.UNRESOLVED),  # not degenerate
    ]
    text = summary(rows)
    assert text.startswith("4 refinements of a worse status, 1 with split's conditions; 3 dropped")
    assert "2 of them OK -> degenerate" in text
    assert "closer to the truth in 1, median 0.300 deg against the kept 0.200" in text
    assert "mean 0.300 against 0.200" in text
