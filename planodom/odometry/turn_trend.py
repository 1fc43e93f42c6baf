"""The yaw rate along its trend, to the epoch's points, for a suspect epoch in a turn
(``odometry.turn_trend_retry``, TURN244).

The pairwise pipelines (the 2D rig's) deskew an epoch first with the prediction, the last
step's angular rate: the mean over the step ``[t_{k-1}, t_k]`` into the previous epoch,
centred ``1.5 dt + tm`` before the new epoch's points (their mean time ``t_k + tm``). Where a
turn tightens steadily that lags by one and a half epochs of the rate's change: on the
2D-rig world 244 at 6 mm, a left turn tightening by about 2.5 deg/s an epoch (21 to 39
deg/s over epochs 34-41), the prediction was 3.1-3.8 deg/s low at epochs 34-36, and
deskewed with it epoch 36 was degenerate (4 planes), while the true twist over its points
gives 5 surfaces and an OK step (docs/RESULTS.md, TURN244).

:func:`turn_trend` extrapolates the yaw rate (about the base frame's z; the roll and pitch
rates of a vehicle sway faster than an epoch and one step measures them poorly, TURNLAG)
along the straight-line trend of the recent epochs' own rates
(:func:`planodom.odometry.trend.trend_twist`, its slope shrunk by how well the fit
determines it: a steady turn or a straight road gives about the mean) to the new epoch's
points' mean time. It is tried by step 1 of :mod:`planodom.odometry.deskew` only when the
epoch deskewed with the prediction is suspect, only when it differs from the prediction by
more than ``deskew_rate_tolerance_deg_s``, and kept only when it ranks higher.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.config import OdometryConfig
from planodom.odometry.trend import trend_twist


def turn_trend(
    rates: Sequence[tuple[int, np.ndarray]],
    k: int,
    times: np.ndarray | None,
    dt: float,
    predicted: np.ndarray | None,
    config: OdometryConfig,
) -> np.ndarray | None:
    """(6,) the twist a suspect epoch ``k`` is tried with under ``config.turn_trend_retry``:
    ``predicted`` (6,) (rad/s, m/s) with its yaw rate replaced by the trend of the
    ``rates`` (epoch, own twist (6,)) extrapolated to the epoch's points' mean time; None
    when off, without a prediction, ``times`` (the points' times, seconds after the epoch
    time) or ``dt`` (seconds since the previous epoch), with fewer than
    ``turn_trend_rates`` rates (the trend is fitted to the last so many), the last not the
    previous epoch's, or a trend within the deskewing tolerance of the prediction.

    An own rate ``j`` is the mean over the step into epoch ``j``, centred at ``j - 1/2`` in
    epochs; the points' mean time ``tm`` lies at ``k + tm / dt``, so the trend is taken at
    ``k + 1/2 + tm / dt`` in the rates' own numbering."""
    if not config.turn_trend_retry or predicted is None or times is None or not len(times):
        return None
    if dt <= 0 or len(rates) < config.turn_trend_rates or rates[-1][0] != k - 1:
        return None
    rates = list(rates)[-config.turn_trend_rates :]
    x = np.array([j for j, _ in rates], dtype=np.float64)
    at = k + 0.5 + float(np.mean(times)) / dt
    yaw = float(trend_twist(np.array([tw for _, tw in rates]), x, at)[2])
    if abs(yaw - float(predicted[2])) <= np.radians(config.deskew_rate_tolerance_deg_s):
        return None
    out = np.array(predicted, dtype=np.float64, copy=True)
    out[2] = yaw
    return out
