"""Tests of planodom.odometry.retry_status against the table ``odometry.retry_accepts`` states."""

from __future__ import annotations

import pytest

from planodom.odometry.retry_status import degenerate_kept


@pytest.mark.parametrize(
    ("accepts", "gap", "kept"),
    [("degenerate", 1, True), ("degenerate", 12, True), ("across_gap", 1, True),
     ("across_gap", 2, False), ("ok", 1, False), ("ok", 12, False)],
)  # fmt: skip
def test_degenerate_kept(accepts: str, gap: int, kept: bool):
    assert degenerate_kept(accepts, gap) is kept
