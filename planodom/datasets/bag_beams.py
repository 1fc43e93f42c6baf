"""The beams of a 2D scanner's message (``LaserScan``, ``MultiEchoLaserScan``): which
ranges are returns (:func:`beam_returns`) and where they lie (:func:`place_beams`), shared
by :mod:`planodom.datasets.bag_msgs` and :mod:`planodom.datasets.bag_multiecho`."""

from __future__ import annotations

from typing import Any

import numpy as np


def beam_returns(ranges: np.ndarray, msg: Any) -> np.ndarray:
    """(n,) bool, the ``ranges`` (n,) float64 m of a LaserScan or MultiEchoLaserScan
    ``msg`` that are returns: finite, in its range limits, not 0 (a driver's "no echo"
    beside a ``range_min`` of 0)."""
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(ranges) & (ranges >= float(msg.range_min)) & (ranges > 0.0)
        if float(msg.range_max) > 0:
            valid &= ranges <= float(msg.range_max)
    return valid


def place_beams(
    msg: Any, r: np.ndarray, beam: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Returns of ranges ``r`` (k,) m on beams ``beam`` (k,) float64 (their indices) as
    ``decode_sweep`` gives a sweep: points (k, 3) in the sensor's x-y plane at angle
    ``angle_min + beam angle_increment``, ring 0, time ``beam time_increment`` s after the
    stamp, 1 ring."""
    a = float(msg.angle_min) + beam * float(msg.angle_increment)
    points = np.column_stack([r * np.cos(a), r * np.sin(a), np.zeros_like(r)])
    return points, np.zeros(len(r), dtype=np.int32), beam * float(msg.time_increment), 1
