"""The odometry the batch smoothing runs (smoothing.odometry_deskew_twist)."""

from __future__ import annotations

from planodom.config import PlanodomConfig
from planodom.smoothing.run import smoothing_config


def test_the_batch_runs_the_coplanar_odometry_when_asked_the_windowed_never():
    cfg = PlanodomConfig().updated({"smoothing.odometry_deskew_twist": "coplanar"})
    assert cfg.odometry.deskew_twist == "predicted"
    assert smoothing_config(cfg, "batch").odometry.deskew_twist == "coplanar"
    assert smoothing_config(cfg, "windowed").odometry.deskew_twist == "predicted"


def test_odometry_keeps_the_odometry_s_own_choice():
    for own in ("predicted", "coplanar"):
        cfg = PlanodomConfig().updated(
            {"smoothing.odometry_deskew_twist": "odometry", "odometry.deskew_twist": own}
        )
        assert smoothing_config(cfg, "batch").odometry.deskew_twist == own
        assert smoothing_config(cfg, "windowed").odometry.deskew_twist == own
