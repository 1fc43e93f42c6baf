"""Configuration of the gate after the batch's solve on the plane map's ties (a part of
:class:`~planodom.config.smoothing.SmoothingConfig`; issue 14's wrong closures)."""

from __future__ import annotations

from typing import Literal

from planodom.config.section import Section


class TieGateConfig(Section):
    """The re-identified ties' gate (planodom.smoothing.tie_gate); fields of the
    ``smoothing`` section."""

    loop_tie_gate_limit: Literal["tail", "bulk"] = "tail"
    """The limit of the chi2 gate after the solve on a re-identified plane factor (a match
    with a tie above it is removed whole): "tail", max(chi2(3)'s ``loop_gate_quantile``,
    the tracked plane factors' own ``loop_gate_quantile`` of their chi2 at the estimate);
    "bulk", the tracked factors' 0.99 quantile carried to ``loop_gate_quantile`` by
    chi2(3)'s ratio of the two quantiles (at least chi2(3)'s quantile). Why: the tracked
    factors' 0.999 quantile is set by their few outliers (lap 388 at 2 cm: median 0.71,
    0.99 quantile 69.7, 0.999 quantile 17 234), so 32 ties of two walls 3 deg apart, at
    chi2 5 958-17 119, passed; the right ties follow the bulk (0.99 quantile 73, largest
    2 438), and "bulk" puts the limit at 99.8. Off by default: not yet judged on fresh
    laps (docs/RESULTS.md, LAPS17)."""
