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


def test_the_coplanar_batch_takes_the_vertical_offset_only_where_z_was_measured():
    """odometry.z_offset_measured_only: None (default) is on in the batch's coplanar
    odometry only; an explicit value is kept everywhere."""
    cfg = PlanodomConfig()
    assert not cfg.odometry.z_offset_measured_only  # planodom run: off
    assert smoothing_config(cfg, "batch").odometry.z_offset_measured_only is True
    assert not smoothing_config(cfg, "windowed").odometry.z_offset_measured_only
    own = cfg.updated({"smoothing.odometry_deskew_twist": "odometry"})
    assert not smoothing_config(own, "batch").odometry.z_offset_measured_only
    for value in (False, True):
        set_ = cfg.updated({"odometry.z_offset_measured_only": value})
        assert smoothing_config(set_, "batch").odometry.z_offset_measured_only is value
