"""The time of the epoch the streaming odometry registers next, checked."""

from __future__ import annotations

import math
from collections.abc import Sequence

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
