"""The unit of a cloud topic's per-point time offsets, from the sweeps' spans and the period.

A ``sensor_msgs/PointField`` has a type but no unit. The documented reading takes integer
offsets as nanoseconds and float ones as seconds (Ouster's ``t``, Livox's ``offset_time``;
Velodyne's ``time``), but a driver may write integer microseconds or float milliseconds.
Read a thousand times too small, the times hardly move (a 0.1 s sweep spans 0.1 ms, so the
sweep is deskewed as if taken at one instant: centimetres of error, and no word); read a
thousand times too large, a sweep spans 100 s and is refused.

The rule needs no threshold fitted to data: a sweep lasts about the period between its
topic's messages (a spinning lidar turns once per message, a Livox integrates for the
period, a driver publishing parts of a turn publishes them as often), so of the two
readings a thousandfold apart the one whose span lies nearer the period (on a log scale:
the boundary is their geometric mean, a factor ``sqrt(1000)``, about 32, either way) is
the unit. Each sweep with a span votes; the majority is the topic's unit, the documented
unit on a tie. A note (one line, for the CLI to warn) says so when the unit is not the
documented one, or when some sweeps voted for the other (a cloud cropped to a sliver of
the turn, a paused driver): there the choice is not clear-cut. Without a period (fewer
than two distinct stamps) or spans, the documented unit is kept. Absolute times (Unix
times, :mod:`planodom.datasets.bag_msgs`) carry their unit in their size and are not
concerned.
"""

from __future__ import annotations

import math
from array import array
from dataclasses import dataclass, field

import numpy as np

from planodom.datasets.bag_clock import SweepBounds
from planodom.datasets.time_wraps import is_32bit, modular_offset_ns

#: The two readings of relative times by field kind: (unit, seconds per unit), documented first.
UNITS: dict[str, tuple[tuple[str, float], tuple[str, float]]] = {
    "integer": (("ns", 1e-9), ("us", 1e-6)),
    "float": (("s", 1.0), ("ms", 1e-3)),
}
UNIT_WORDS = {"ns": "nanoseconds", "us": "microseconds", "s": "seconds", "ms": "milliseconds"}


def time_key(name: str, dtype: np.dtype) -> tuple[str, str]:
    """What a unit is chosen for: a time field's name and kind (``integer`` or ``float``).
    A topic's clouds may change layout mid-bag (a driver relaunched: Velodyne's ``time``
    in float seconds, then Ouster's ``t`` in integer nanoseconds); each field has its own."""
    return name, "integer" if np.dtype(dtype).kind in "iu" else "float"


def unit_of(scale: float) -> str | None:
    """The unit of :data:`UNITS` whose seconds per unit are ``scale``, None for another."""
    return next((unit for pair in UNITS.values() for unit, s in pair if s == scale), None)


@dataclass
class TopicTimes:
    """What the index pass learnt of one cloud topic's relative per-point times.

    Attributes:
        name: the time field read ("" until a sweep with relative times is seen).
        dtype: its type (numpy's name, e.g. ``uint32``).
        spans: per such sweep, its times' span (max - min) in the field's own unit.
        sweeps: per span, the caller's number for its sweep (-1 without one).
        largest: the largest ``|time|`` of any sweep, in the field's own unit.
        plain, cut: per sweep of a 32-bit integer field with a stamp, its largest
            ``|value|`` and its largest distance from the stamp's lowest 32 bits (ns;
            :mod:`planodom.datasets.time_wraps`).
        bounds: per sweep its earliest and latest value (the field's unit) and its stamp
            (:mod:`planodom.datasets.bag_clock`).
    """

    name: str = ""
    dtype: str = ""
    spans: array = field(default_factory=lambda: array("d"))
    sweeps: array = field(default_factory=lambda: array("q"))
    largest: float = 0.0
    plain: array = field(default_factory=lambda: array("d"))
    cut: array = field(default_factory=lambda: array("d"))
    bounds: SweepBounds = field(default_factory=SweepBounds)

    def add(self, name: str, values: np.ndarray, sweep: int = -1, stamp: int = 0) -> None:
        """Add one sweep's relative times ``values`` (n,) (finite, the field's own type);
        ``sweep``: a number for it, which :meth:`without` can name; ``stamp``: its stamp,
        ns (0: none)."""
        self.name, self.dtype = name, values.dtype.name
        if len(values):
            low, high = float(values.min()), float(values.max())
            self.spans.append(high - low)
            self.sweeps.append(sweep)
            self.largest = max(self.largest, abs(low), abs(high))
            self.bounds.add(name, self.dtype, low, high, stamp)
            if stamp and is_32bit(values.dtype):
                self.plain.append(max(abs(low), abs(high)))
                self.cut.append(modular_offset_ns(values, stamp))

    def without(self, sweeps: np.ndarray) -> TopicTimes:
        """These times without the spans of the sweeps numbered ``sweeps`` (k,) (so that a
        message recorded twice votes once); itself when there are none."""
        if not len(sweeps):
            return self
        keep = ~np.isin(np.frombuffer(self.sweeps, dtype=np.int64), sweeps)
        spans = np.frombuffer(self.spans, dtype=np.float64)[keep]
        numbers = np.frombuffer(self.sweeps, dtype=np.int64)[keep]
        return TopicTimes(
            self.name,
            self.dtype,
            array("d", spans.tolist()),
            array("q", numbers.tolist()),
            self.largest,
        )

    @property
    def kind(self) -> str:
        """``integer`` or ``float``."""
        return "integer" if np.dtype(self.dtype).kind in "iu" else "float"


@dataclass(frozen=True)
class TimeUnit:
    """The reading chosen for a topic's relative times.

    Attributes:
        unit: ``ns``, ``us``, ``s`` or ``ms``; scale: seconds per unit.
        note: one line when the unit is not the documented one, the sweeps disagree, or
            neither reading spans near the period (else None); the caller adds the topic.
    """

    unit: str
    scale: float
    note: str | None = None


def _duration(seconds: float) -> str:
    """``seconds`` in the unit that reads best (``0.1 ms``, ``99.6 ms``, ``12 s``)."""
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9)):
        if abs(seconds) >= scale or unit == "ns":
            return f"{seconds / scale:.3g} {unit}"
    return f"{seconds:g} s"  # pragma: no cover


def period_s(stamps_ns: np.ndarray) -> float | None:
    """The median step (s) between a topic's distinct message stamps, None below two."""
    steps = np.diff(np.unique(np.asarray(stamps_ns, dtype=np.int64)))
    return float(np.median(steps)) * 1e-9 if len(steps) else None


def choose_unit(times: TopicTimes, stamps_ns: np.ndarray, between: str = "messages") -> TimeUnit:
    """The unit of a topic's relative times (see the module docstring).

    Args:
        times: the spans of its sweeps (:class:`TopicTimes`).
        stamps_ns: (n,) int64 its messages' stamps, ns.
        between: what the stamps are of, for the note (``messages``, ``epochs``).
    """
    (doc, doc_scale), (alt, alt_scale) = UNITS[times.kind]
    spans = np.frombuffer(times.spans, dtype=np.float64)
    spans = spans[spans > 0]
    period = period_s(stamps_ns)
    if period is None or len(spans) == 0:
        return TimeUnit(doc, doc_scale)
    # log distance of each sweep's span from the period under either reading
    off_doc = np.abs(np.log(spans * doc_scale / period))
    off_alt = np.abs(np.log(spans * alt_scale / period))
    votes_alt = int(np.count_nonzero(off_alt < off_doc))
    votes_doc = len(spans) - votes_alt
    unit, scale = (alt, alt_scale) if votes_alt > votes_doc else (doc, doc_scale)
    median = float(np.median(spans))
    what = f"time field '{times.name}' ({times.dtype})"
    other = doc if unit == alt else alt
    other_scale = doc_scale if unit == alt else alt_scale
    spread = (
        f"as {UNIT_WORDS[other]} a sweep would span {_duration(median * other_scale)} of the "
        f"{_duration(period)} between {between}, as {UNIT_WORDS[unit]} "
        f"{_duration(median * scale)} (median)"
    )
    against = votes_doc if unit == alt else votes_alt
    # neither reading within the vote's boundary of the period (integer milliseconds read
    # as microseconds: a 0.1 s sweep as 0.1 ms, deskewing as good as off)
    far = abs(math.log(median * scale / period)) > 0.5 * math.log(1000.0)
    neither = "; neither reading spans near the period: another unit, or sweeps cut short?"
    ignore = f"{neither if far else ''}; --time-field none ignores the times"
    if against:
        note = (
            f"{what} read as {UNIT_WORDS[unit]}, but not clear-cut: {against} of "
            f"{len(spans)} sweeps span nearer the period as {UNIT_WORDS[other]}; {spread}{ignore}"
        )
        return TimeUnit(unit, scale, note)
    if unit == alt:
        note = f"{what} read as {UNIT_WORDS[unit]}, not {UNIT_WORDS[doc]}: {spread}{ignore}"
        return TimeUnit(unit, scale, note)
    if far:
        return TimeUnit(unit, scale, f"{what} read as {UNIT_WORDS[unit]}: {spread}{ignore}")
    return TimeUnit(unit, scale)
