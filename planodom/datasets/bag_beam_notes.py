"""Ways a 2D scan topic is read that a user should know of: :func:`beam_notes`.

- A beam count that changes from one message to the next (``LaserScan`` or
  ``MultiEchoLaserScan``): a driver relaunched with another resolution or field of view,
  or two scanners publishing on one topic. Each message is read with its own angles
  (``angle_min + i angle_increment``), so its points are right, but the topic is then
  perhaps not the one scanner the rig takes it for.
- ``--echo strongest`` on a ``MultiEchoLaserScan`` topic whose messages carry no
  intensities for beams with echoes: those beams' strongest echo is unknown and their
  first return is read (:mod:`planodom.datasets.bag_multiecho`), as ``--echo first`` would.
- A ``range_min`` above a positive ``range_max`` (the limits swapped in the driver's
  settings): no range lies within them, so the message holds no return and is read as an
  empty scan (a rig of one scanner then has no point at all, a rig of several loses one).
- A ``time_increment`` of 0 under several beams (a driver that gives no beam times, or a
  converter such as pointcloud_to_laserscan): every beam is read at the stamp, so the
  scan is not deskewed.

None changes a point read; they only count, during the index pass.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from planodom.datasets.bag_multiecho import MULTI_ECHO

#: The beam counts shown in the note; more are summed up as "…".
SHOWN = 3


@dataclass
class BeamCounts:
    """A 2D scan topic's beam counts and intensities, counted message by message.

    Attributes:
        messages: messages by beam count (``len(ranges)``), in first-seen order.
        unlit: MultiEchoLaserScans with a beam that holds echoes but no intensities.
        unlit_beams: those beams, over all such messages.
        swapped: messages whose ``range_min`` lies above their positive ``range_max``;
            limits: the first such message's ``(range_min, range_max)``, m.
        untimed: messages of several beams with a ``time_increment`` of 0; scan_time: the
            first such message's ``scan_time``, s.
    """

    messages: dict[int, int] = field(default_factory=dict)
    unlit: int = 0
    unlit_beams: int = 0
    swapped: int = 0
    limits: tuple[float, float] = (0.0, 0.0)
    untimed: int = 0
    scan_time: float = 0.0

    def add(self, msg: Any, msgtype: str) -> None:
        """Count a LaserScan's or MultiEchoLaserScan's beams (and, for the latter, its
        beams with echoes but without intensities; its intensities already checked
        against its ranges, :func:`.bag_multiecho.echo_arrays`)."""
        beams = len(msg.ranges)
        self.messages[beams] = self.messages.get(beams, 0) + 1
        low, high = float(msg.range_min), float(msg.range_max)
        if high > 0.0 and low > high:
            self.limits = self.limits if self.swapped else (low, high)
            self.swapped += 1
        if beams > 1 and float(msg.time_increment) == 0.0:
            self.scan_time = self.scan_time if self.untimed else float(msg.scan_time)
            self.untimed += 1
        if msgtype != MULTI_ECHO:
            return
        echoes = np.array([len(e.echoes) for e in msg.ranges], dtype=np.int64)
        lit = np.zeros(beams, dtype=np.int64)
        if len(msg.intensities):
            lit = np.array([len(e.echoes) for e in msg.intensities], dtype=np.int64)
        unlit = int(np.count_nonzero((echoes > 0) & (lit == 0)))
        self.unlit += unlit > 0
        self.unlit_beams += unlit


def beam_notes(topic: str, sweeps: int, counts: BeamCounts, echo: str) -> list[str]:
    """The notes (module docstring) on ``topic`` of ``sweeps`` messages, read with
    ``echo`` (``BagOptions.echo``): one line each, naming the topic, the case and how many
    of its messages it touches."""
    notes = []
    if len(counts.messages) > 1:
        ranked = sorted(counts.messages.items(), key=lambda bn: -bn[1])  # stable: first seen
        shown = ", ".join(f"{b} in {n}" for b, n in ranked[:SHOWN])
        more = ", …" if len(ranked) > SHOWN else ""
        notes.append(
            f"topic '{topic}': its {sweeps} messages hold {len(ranked)} beam counts (beams in "
            f"messages: {shown}{more}: a driver relaunched with another resolution or field "
            "of view, or two scanners on one topic?); each is read with its own angles"
        )
    if echo == "strongest" and counts.unlit:
        notes.append(
            f"topic '{topic}': {counts.unlit} of {sweeps} messages carry no intensities for "
            f"beams with echoes ({counts.unlit_beams} beams in all): --echo strongest reads "
            "those beams' first return"
        )
    if counts.swapped:
        low, high = counts.limits
        notes.append(
            f"topic '{topic}': {counts.swapped} of {sweeps} messages have a range_min of "
            f"{low:g} m above their range_max of {high:g} m (the limits swapped in the "
            "driver's settings?): no range lies within them, so they are read without a return"
        )
    if counts.untimed:
        notes.append(
            f"topic '{topic}': {counts.untimed} of {sweeps} messages have a time_increment of "
            f"0 (scan_time {counts.scan_time:g} s): their beams are all read at the stamp, "
            "not deskewed (a driver or a converter such as pointcloud_to_laserscan that "
            "gives no beam times)"
        )
    return notes
