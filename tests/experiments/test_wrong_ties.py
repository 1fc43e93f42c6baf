"""experiments/wrong_ties.py: a rotation-only tie's offset residuals, against hand-made ones."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from experiment_scripts import load_script


def _script():
    return load_script("wrong_ties")


def test_offset_note_names_the_tied_wall_and_the_nearest_other() -> None:
    # two ties: landmark 5 tied to old plane 2 (residual +0.05 m), landmark 7 to plane 0;
    # plane 1 is not parallel to either (NaN); the others of landmark 5's row: -2.91, +0.97
    offsets = SimpleNamespace(
        residuals=np.array([[-2.91, np.nan, 0.05, 0.97], [0.40, np.nan, -1.2, np.nan]]),
        tied=np.array([2, 0]),
    )
    match = SimpleNamespace(ties=[(5, 3), (7, 4)], offsets=offsets)
    note = _script().offset_note(match, 5)
    assert "tied +0.05 m" in note and "nearest other parallel wall 0.97 m" in note
    note = _script().offset_note(match, 7)
    assert "tied +0.40 m" in note and "nearest other parallel wall 1.20 m" in note


def test_offset_note_is_empty_for_a_full_match() -> None:
    match = SimpleNamespace(ties=[(5, 3)], offsets=None)
    assert _script().offset_note(match, 5) == ""
