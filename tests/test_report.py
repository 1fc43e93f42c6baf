"""The odometry summary table's front end speed on slow runs."""

from __future__ import annotations

from rich.console import Console

from planodom.report import odometry_table


def _text(metrics: dict[str, float]) -> str:
    console = Console(width=120, record=True)
    console.print(odometry_table(None, metrics))
    return console.export_text()


def test_a_slow_front_end_speed_is_not_shown_as_zero() -> None:
    # 3 epochs of 10M points each took 387 s: one decimal showed "0.0 epochs/s"
    assert "0.0078 epochs/s (129 s an epoch)" in _text({"epochs_per_second": 3 / 387})
    assert "12.3 epochs/s" in _text({"epochs_per_second": 12.34})
