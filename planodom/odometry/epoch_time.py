"""The time of the epoch the streaming odometry registers next, checked; gaps in the
epoch times (one definition, for the odometry and the run's warning)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from planodom.errors import GeometryError


def next_epoch_time(time: float | None, times: Sequence[float], period_s: float) -> float:
    """The time (s) of epoch ``len(times)``: ``time``, or the last of ``times`` plus
    ``period_s`` (0 for the first epoch).

    Raises:
        GeometryError: a ``time`` that is not finite, or not after the last of ``times``
            (a step over zero or negative time has no velocity: the deskewing and the
            constant-velocity bridge would be silently wrong).
    """
    if time is None:
        return times[-1] + period_s if len(times) else 0.0
    t = float(time)
    if not math.isfinite(t) or (len(times) and not t > times[-1]):
        after = f" after the previous epoch's {times[-1]!r} s" if len(times) else ""
        raise GeometryError(
            f"epoch {len(times)}: time {t!r} s is not a finite time{after}; "
            "epoch times must increase"
        )
    return t


#: A step of this many epoch periods or more (rounded, :func:`epoch_periods`) is a gap in
#: the epoch times (a scan missing, a paused or cut recording): the run warns of it
#: (``epochs_after_gaps`` in metrics.json).
GAP_PERIODS = 2

#: Across a gap of this many epoch periods or more (:func:`is_gap`) the streaming odometry
#: (:class:`planodom.odometry.odometry.PlaneOdometry`) carries no motion. Shorter gaps (a scan or a
#: few dropped) keep the constant-velocity prediction, which is still right over them (two scans
#: dropped from a lidar16 world at 3.4 m/s: that epoch 0.4 cm off with it, 1.0 cm without). Ten
#: periods (a second at 10 Hz, long enough for a vehicle to stop or turn) is a judgment, not fitted
#: to data. The epoch after a gap is registered without a prediction (standing still; the plane
#: map's too, its twist filter started again), deskewed with the twist held from before the gap and
#: not extracted again, and its step gives no twist (the recent twists are dropped; the one held
#: goes on to the next epoch, whose own step is measured again). Not without deskewing, as after an
#: unresolved epoch: there the epoch's own step then refines the twist, but a step across a gap
#: measures none, and nothing marks the skewed epoch as suspect. A recording of a random world
#: (lidar16, 3.4 m/s) with an hour cut out before epoch 20: that epoch 19 cm off before (the step's
#: twist over 3600 s deskewed it as standing still), 0.6 cm after; 18 cm extracted without deskewing
#: (the held twist only a rescue, as after an unresolved epoch).
RESET_PERIODS = 10

#: The steps :func:`is_gap` judges the period by: the last ones only (a percentile over a
#: whole run at every epoch would cost its length squared).
_RECENT_STEPS = 100


def epoch_periods(times: Sequence[float]) -> np.ndarray:
    """(E - 1,) the time steps of ``times`` (E,) in epoch periods, rounded; the period is
    the lower quartile of the steps, which a few gaps leave alone; ones when the steps
    are not positive (or E < 2: empty)."""
    dt = np.diff(np.asarray(times, dtype=np.float64))
    period = float(np.percentile(dt, 25)) if len(dt) else 0.0
    return np.rint(dt / period) if period > 0 else np.ones(len(dt))


def is_gap(times: Sequence[float], t: float) -> bool:
    """Whether the step from the last of ``times`` (s) to ``t`` (s) is a gap the odometry
    carries no motion across (:data:`RESET_PERIODS`), judged as the streaming odometry
    can: by the recent steps so far (``times`` then ``t``). Never within the first two
    steps (no period to judge by)."""
    if len(times) < 2:
        return False
    # epoch_periods(...)[-1] in plain floats (asked once an epoch; numpy's percentile
    # costs more than the rest of the test): the same steps, quartile and rounding
    recent = [*times[-(_RECENT_STEPS + 1) :], t]
    steps = [float(b) - float(a) for a, b in zip(recent[:-1], recent[1:], strict=True)]
    period = lower_quartile(steps)
    return period > 0 and round(steps[-1] / period) >= RESET_PERIODS


def lower_quartile(values: Sequence[float]) -> float:
    """``np.percentile(values, 25)`` (the same value, default linear method) of finite
    ``values`` (n >= 1) without numpy: the two order statistics around ``(n - 1) / 4``
    and numpy's interpolation between them, ``a + (b - a) g`` below ``g = 0.5``, else
    ``b - (b - a)(1 - g)``."""
    s = sorted(values)
    if len(s) == 1:
        return s[0]
    virtual = (len(s) - 1) * 0.25
    i = math.floor(virtual)
    g = virtual - i
    a, b = s[i], s[i + 1]
    d = b - a
    return b - d * (1 - g) if g >= 0.5 else a + d * g
