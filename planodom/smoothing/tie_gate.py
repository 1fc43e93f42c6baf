"""The limit of the gate after the batch's solve on the plane map's ties
(:func:`planodom.smoothing.loop_records.gate_reidentifications`)."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

#: The tracked factors' quantile that "bulk" reads: inside their inlier bulk on the laps
#: (lap 388 at 2 cm: 50 of 5 045 factors above it), where a few dozen outliers do not set it.
BULK_QUANTILE = 0.99


def tie_gate_limit(tracked: np.ndarray, quantile: float, mode: str) -> float:
    """Squared whitened error above which a re-identified plane factor fails the gate.

    ``tracked`` (N,): the tracked plane factors' chi2 (squared whitened errors, 3 DoF) at
    the estimate; ``quantile``: ``loop_gate_quantile``; ``mode``:
    ``smoothing.loop_tie_gate_limit``. "tail": the larger of chi2(3)'s ``quantile`` and the
    tracked factors' own ``quantile``. "bulk": the tracked factors' :data:`BULK_QUANTILE`
    scaled by chi2(3)'s ``quantile`` over its :data:`BULK_QUANTILE` (were the tracked
    factors chi2(3) times a scale, both give that scale's ``quantile``; their outliers move
    the tail's, not the bulk's), at least chi2(3)'s ``quantile``. No tracked factor: chi2(3)'s.
    """
    floor = float(chi2.ppf(quantile, 3))
    if len(tracked) == 0:
        return floor
    if mode == "bulk":
        ratio = floor / float(chi2.ppf(BULK_QUANTILE, 3))
        return max(floor, float(np.quantile(tracked, BULK_QUANTILE)) * ratio)
    return max(floor, float(np.quantile(tracked, quantile)))
