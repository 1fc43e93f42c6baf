"""A bag topic's per-point times on another clock than its stamps': far from every point.

A lidar's sweep lasts about the period between its topic's messages and its driver stamps
it at its start or its end (or when its last packet arrived, a few milliseconds later), so
the stamp lies within or next to the span of the sweep's point times. Per-point times on
another clock than the stamps' do not: a lidar's own clock read as absolute times while
the stamps are the host's (a clock off by a fraction of a second up to the
:data:`~planodom.datasets.bag_msgs.MAX_SWEEP_OFFSET_S` that the decoder refuses beyond),
or offsets counted from the recording's start instead of each sweep's stamp. Read as
they are, every point of a sweep is deskewed by the motion of that gap, so the sweep is
placed along the trajectory where the vehicle was then: metres off at walking speed, no
word. Such times are refused when the nearest point of at least half a topic's sweeps
lies more than :data:`~planodom.datasets.time_wraps.CUT_PERIODS` periods from its stamp,
the bound the 32-bit clock check uses for the same reason (a sweep lies within one period
of its stamp; the second leaves room for a stamp taken late; not fitted to data); fewer
such sweeps are noted and read (stamps taken late while a recorder stalled, the points'
own times right). Without a period (fewer than two distinct stamps) nothing is refused.

A Livox ``CustomMsg``'s times (its ``timebase`` plus each point's ``offset_time``) are
held to the same bounds (:func:`livox_time_error`), which nothing checked before. Absolute
times in a float32 field are refused too (:func:`check_absolute_type`): at a
Unix time a float32 steps by 128 s, so a sweep's times are lost, each put up to a minute
from the truth (or all at one), which the 10 s bound catches only by chance.
"""

from __future__ import annotations

from array import array
from dataclasses import dataclass, field

import numpy as np

from planodom.datasets.time_wraps import CUT_PERIODS


@dataclass
class SweepBounds:
    """Per sweep of one time field of a topic: the earliest and latest point time after
    its stamp (``lows``, ``highs``: in the field's unit for offsets, seconds for absolute
    times) and its stamp (``stamps``, ns)."""

    name: str = ""
    dtype: str = ""
    lows: array = field(default_factory=lambda: array("d"))
    highs: array = field(default_factory=lambda: array("d"))
    stamps: array = field(default_factory=lambda: array("q"))

    def add(self, name: str, dtype: str, low: float, high: float, stamp: int) -> None:
        """One sweep's earliest and latest time after its ``stamp`` (ns)."""
        self.name, self.dtype = name, dtype
        self.lows.append(low)
        self.highs.append(high)
        self.stamps.append(stamp)


def clock_error(
    bounds: SweepBounds, scale: float, period: float | None, kind: str
) -> tuple[bool, str] | None:
    """Whether a topic's time field is refused as another clock than its stamps' (see the
    module docstring) and why, or None when every sweep lies near its stamp.

    At least half its sweeps far from their stamps: refused (``True``; a clock off, or
    offsets counted from the recording's start, put every sweep, or every sweep after the
    first few, far). Fewer: a note (``False``), the times read as they are: stamps taken
    late for a while (a recorder stalled, then catching up: receipt times bunched) with
    per-point times that are right.

    Args:
        bounds: its sweeps' earliest and latest times after their stamps.
        scale: seconds per unit of ``bounds`` (1.0 for absolute times, already seconds).
        period: the topic's period between messages, s (None: fewer than two stamps).
        kind: ``absolute times`` or ``offsets``, how the field was read (for the message).
    """
    if period is None or not len(bounds.lows):
        return None
    lows = np.frombuffer(bounds.lows, dtype=np.float64) * scale
    highs = np.frombuffer(bounds.highs, dtype=np.float64) * scale
    gaps = np.maximum(np.maximum(lows, -highs), 0.0)  # the stamp to the sweep's nearest point
    far = gaps > CUT_PERIODS * period
    if not far.any():
        return None
    k = int(np.flatnonzero(far)[0])
    stamp = int(bounds.stamps[k])
    field = (
        f"PointCloud2 time field '{bounds.name}' ({bounds.dtype}, read as {kind})"
        if bounds.dtype
        else f"Livox CustomMsg point times ({bounds.name})"
    )
    where = (
        f"{field} put{'s' if bounds.dtype else ''} {int(far.sum())} of {len(gaps)} sweeps "
        f"away from their stamps: the nearest point more than {CUT_PERIODS:g} periods "
        f"({CUT_PERIODS * period:.3g} s) from its stamp, up to {float(gaps.max()):.3g} s (first "
        f"the sweep stamped {stamp // 10**9}.{stamp % 10**9:09d} s, its points "
        f"{lows[k]:+.3g} to {highs[k]:+.3g} s from it)"
    )
    if 2 * int(far.sum()) < len(gaps):
        return False, f"{where}: stamps taken late (a recorder stalled?); read as they are"
    what = (
        "absolute times on another clock than the stamps' (the lidar's own, not synchronised?)"
        if kind != "offsets"
        else "offsets from another time than each sweep's stamp (the recording's start?)"
    )
    return True, (
        f"{where}: {what}, which would deskew each sweep by that much motion; --time-field "
        "none ignores them"
    )


def check_absolute_type(raw: np.ndarray, time_name: str) -> None:
    """ValueError when absolute times ``raw`` (n,) are in a float32 field: at a Unix time
    (1.7e9 s, or 1.7e18 ns) a float32 steps by 128 s, so a sweep's 0.1 s is lost and its
    points are put up to a minute from their time (or all at one)."""
    if raw.dtype != np.float32:
        return
    largest = float(np.nanmax(np.abs(raw.astype(np.float64))))
    step = float(np.spacing(np.float32(largest)))
    unit = "ns" if largest > 1e15 else "s"
    raise ValueError(
        f"PointCloud2 time field '{time_name}' (float32) holds absolute times ({largest:.4g} "
        f"{unit}), which a float32 rounds to steps of {step:.3g} {unit}: each point's time is "
        "lost (store offsets from the stamp, or float64); --time-field none ignores it"
    )


def far_message(t: np.ndarray, near: float, period: float) -> str:
    """Why a scan file's point times ``t`` (n,) s from its epoch's time, whose nearest lies
    ``near`` s from it, are refused (the dataset reader's version of :func:`clock_error`;
    ``period``: the epochs' period there, s; the caller names the file)."""
    return (
        f"point times lie {float(t.min()):+.3g} to {float(t.max()):+.3g} s from the epoch's "
        f"reference time, the nearest more than {CUT_PERIODS:g} epoch periods of {period:.3g} "
        "s from it: another clock than the epoch times' (poses.tum / times.txt), or offsets "
        "from another time (the recording's start?), which would deskew the scan by "
        f"{near:.3g} s of motion; --time-field none ignores them"
    )


def livox_time_error(dt: np.ndarray, bound: float) -> str | None:
    """Why a Livox CustomMsg's point times ``dt`` (n,) s after its header stamp
    (``timebase + offset_time``) are refused, when one lies beyond ``bound`` s (the
    decoder's bound for any sweep) or is not finite, or None."""
    if not len(dt) or np.all(np.abs(dt) <= bound):
        return None
    worst = float(dt[np.argmax(np.nan_to_num(np.abs(dt), nan=np.inf))])
    return (
        f"Livox CustomMsg's timebase + offset_time put a point {worst:.6g} s from its header "
        f"stamp, beyond {bound:g} s: its timebase is not on the stamps' clock (the lidar's "
        "own, not synchronised, and the messages stamped again?); --time-field none ignores "
        "the point times"
    )
