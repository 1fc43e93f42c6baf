"""The loop experiment's summary (planodom.experiments.loops.summary_rows) on hand-made rows."""

from __future__ import annotations

import numpy as np

from planodom.experiments.loops import summary_rows


def test_summary_counts_loop_factors_and_wrong_ones_over_worlds():
    rows = [
        {"noise_mm": 6.0, "method": "batch+loops", "ate_m": a, "loop_end_m": e,
         "wrong_kept": 0, "loop_factors": n, "loop_factors_wrong_kept": w}
        for a, e, n, w in ((0.1, 0.05, 4, 1), (0.3, 0.2, 6, 0), (0.2, 0.1, 0, 0))
    ]  # fmt: skip
    rows.append({"noise_mm": 6.0, "method": "odometry", "ate_m": 2.0, "loop_end_m": 3.0})
    out = {r["method"]: r for r in summary_rows(rows)}
    loops = out["batch+loops"]
    assert loops["worlds"] == 3 and loops["median_ate_m"] == 0.2 and loops["worst_ate_m"] == 0.3
    assert loops["loop_factors"] == 10 and loops["wrong_loop_factors"] == 1
    assert out["odometry"]["loop_factors"] == 0


def test_summary_fixed_lag_loops_ties_and_median_rate():
    rows = [
        {"noise_mm": 20.0, "method": "windowed+loops", "ate_m": 0.5, "loop_end_m": 0.4,
         "reidentified": n, "wrong_kept": w, "epochs_per_s": r}
        for n, w, r in ((10, 0, 80.0), (30, 2, 100.0), (5, 0, 120.0))
    ]  # fmt: skip
    rows.append({"noise_mm": 20.0, "method": "oracle", "ate_m": 0.01, "loop_end_m": 0.01})
    out = {r["method"]: r for r in summary_rows(rows)}
    fl = out["windowed+loops"]
    assert fl["ties_kept"] == 45 and fl["wrong_kept"] == 2 and fl["median_epochs_per_s"] == 100.0
    assert np.isnan(out["oracle"]["median_epochs_per_s"]) and out["oracle"]["ties_kept"] == 0
