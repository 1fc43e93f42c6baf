"""Notes on a cloud topic whose sweeps are not deskewed although they may carry times.

Two layouts read without a word before: clouds whose point times are in a field under a
name none of the drivers' names planodom reads (a converter's ``time_offset`` beside
``timebase_low`` / ``timebase_high``), and a time field that holds one value for all the
points of each sweep (a driver that fills no per-point time, or a flash lidar's snapshot).
Either way each sweep is taken at one instant; the note names the fields, and
``--time-field NAME`` reads one of them.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from planodom.datasets.bag_clock import SweepBounds
from planodom.datasets.bag_time_units import TopicTimes
from planodom.datasets.scan_io import TIME_FIELDS


def time_like_fields(fields: Sequence[tuple[str, str]]) -> dict[str, str]:
    """The fields ``(name, numpy type)`` whose name says they may hold times (``time`` or
    ``stamp`` in it, any case) but that are not among the names read (:data:`TIME_FIELDS`),
    or are but of a PointField type that is not read (``type 9``: no ROS type)."""
    return {
        name: dtype
        for name, dtype in fields
        if ("time" in name.lower() or "stamp" in name.lower() or name in TIME_FIELDS)
        and (name not in TIME_FIELDS or dtype.startswith("type "))
    }


def unread_time_note(topic: str, untimed: int, clouds: int, fields: Mapping[str, str]) -> str:
    """The note on a topic's ``untimed`` of ``clouds`` clouds read without a time field
    while they have the time-like ``fields`` (name -> type), or ""."""
    if not untimed or not fields:
        return ""
    shown = ", ".join(
        f"'{n}' ({'PointField ' + d + ', not read' if d.startswith('type ') else d})"
        for n, d in fields.items()
    )
    readable = [n for n, d in fields.items() if not d.startswith("type ")]
    advice = (
        f"; if {'it holds' if len(fields) == 1 else 'one holds'} each point's time from the "
        f"stamp (or since the Unix epoch), --time-field {readable[0]} reads it"
        if readable
        else ""
    )
    return (
        f"topic '{topic}': {untimed} of {clouds} clouds have none of the time fields read "
        f"({', '.join(TIME_FIELDS)}) but {shown}: their sweeps are not deskewed{advice}"
    )


def one_time_notes(
    topic: str, times: Mapping[tuple[str, str], TopicTimes], absolute: Mapping[str, SweepBounds]
) -> list[str]:
    """The notes on a topic's time fields that hold one value for all the points of each
    of its sweeps (two or more sweeps with points), or []."""
    flat = [
        (t.name, t.dtype, len(t.spans))
        for t in times.values()
        if len(t.spans) > 1 and not np.any(np.frombuffer(t.spans, dtype=np.float64))
    ]
    for b in absolute.values():
        lows, highs = (np.frombuffer(a, dtype=np.float64) for a in (b.lows, b.highs))
        if b.dtype and len(lows) > 1 and np.array_equal(lows, highs):  # not a Livox message
            flat.append((b.name, b.dtype, len(lows)))
    return [
        f"topic '{topic}': time field '{name}' ({dtype}) holds one value for all the points "
        f"of each of its {n} sweeps: each is taken at one instant, not deskewed (a driver "
        "that fills no per-point time?)"
        for name, dtype, n in flat
    ]
