"""Point times in a 32-bit integer field that are a clock's nanoseconds cut to 32 bits.

A driver or a conversion that stores a Unix time in nanoseconds in a ``uint32`` (or
``int32``) field keeps its lowest 32 bits: a clock that wraps every 2^32 ns (4.29 s). Read
as offsets (the documented reading of integer times) such values put the points of a 0.1
s sweep anywhere up to 4.29 s from their stamp, and a sweep in which the clock wraps spans
4.29 s. Nothing else refused them in a bag (offsets up to
:data:`~planodom.datasets.bag_msgs.MAX_SWEEP_OFFSET_S` are read: deskewing garbage, the
points metres off, no word), and a scan file's were refused with a message suggesting
milliseconds. They are recognised without a threshold fitted to data:

- in any cloud, a 32-bit field whose values span more than half their type's range as
  numbers but a shorter arc of the 2^32 circle across its wrap: the values wrap
  (:func:`wraps_inside`);
- in a bag, where each sweep has a stamp on the Unix clock: every sweep's values lie within
  two periods of its stamp's lowest 32 bits, taken round the circle, and some sweep's
  values read as offsets lie further from the stamp than that (:func:`cut_clock_error`).
  Offsets that are offsets lie within a period of the stamp either way; a sweep's stamp
  whose lowest bits fall near its offsets by chance (about one in twenty at 10 Hz) does
  not make the read offsets far.

Such times are refused (one line naming the field) rather than read modulo 2^32: their
start against the epoch's time is known only in a bag, and a driver that cuts its clock
may well have cut it from another clock than the stamps'.
"""

from __future__ import annotations

import numpy as np

#: The period of a 32-bit nanosecond clock, ns (4.29 s).
WRAP_NS = 2**32
#: How far (in the topic's periods) a sweep's times may lie from its stamp read modulo
#: 2^32 to count as the stamp's clock cut to 32 bits: a sweep lies within one period of
#: its stamp, before or after it; two leave room for a stamp taken late (not from data).
CUT_PERIODS = 2.0
ADVICE = (
    "store offsets from the sweep's stamp, or 64-bit absolute times (--time-field none "
    "ignores them)"
)


def is_32bit(dtype: np.dtype) -> bool:
    """Whether ``dtype`` is a 32-bit integer type (``uint32``, ``int32``)."""
    return np.dtype(dtype).kind in "iu" and np.dtype(dtype).itemsize == 4


def _circle_span(raw: np.ndarray) -> int:
    """The shortest arc (in units) of the 2^32 circle that holds the values (n,) of a
    32-bit field: 2^32 less the largest gap between them taken round the circle."""
    circle = np.sort(raw.astype(np.int64) % WRAP_NS)
    across = int(circle[0]) + WRAP_NS - int(circle[-1])  # the gap across 0
    return WRAP_NS - max(int(np.diff(circle).max(initial=0)), across)


def wraps_inside(raw: np.ndarray) -> bool:
    """Whether the values (n,) of a 32-bit integer field wrap round 2^32 among themselves:
    they span more than half the circle as numbers, but a shorter arc of it round the wrap
    (so they are near each other across it)."""
    if not is_32bit(raw.dtype) or len(raw) < 2:
        return False
    span = int(raw.astype(np.int64).max()) - int(raw.astype(np.int64).min())
    return span > WRAP_NS // 2 and _circle_span(raw) < span


def wrap_message(name: str, raw: np.ndarray) -> str:
    """The one-line reason a field ``name`` of values ``raw`` (n,) that wrap is refused."""
    span_s = _circle_span(raw) * 1e-9
    info = np.iinfo(raw.dtype)
    return (
        f"point times '{name}' ({raw.dtype}) wrap round 2^32 within the sweep (values near "
        f"{info.min} and near {info.max}, {span_s:.3g} s apart across the wrap): a clock's "
        f"nanoseconds cut to 32 bits, which wrap every {WRAP_NS * 1e-9:.3g} s; " + ADVICE
    )


def modular_offset_ns(raw: np.ndarray, stamp: int) -> int:
    """The largest distance (ns) of the values (n,) of a 32-bit field from the lowest 32
    bits of ``stamp`` (ns), each taken round the 2^32 circle (the shorter way)."""
    d = (raw.astype(np.int64) - stamp) % WRAP_NS
    return int(np.minimum(d, WRAP_NS - d).max())


def cut_clock_error(
    name: str, dtype: str, plain_ns: np.ndarray, cut_ns: np.ndarray, period: float | None
) -> str | None:
    """Why a bag topic's 32-bit time field ``name`` is refused as its stamps' clock cut to
    32 bits (see the module docstring), or None.

    Args:
        dtype: the field's type (numpy's name); plain_ns: (k,) per sweep, the largest
            ``|value|`` (ns, read as offsets); cut_ns: (k,) per sweep, the largest distance
            of its values from its stamp's lowest 32 bits (:func:`modular_offset_ns`);
            period: the topic's period between messages, s (None: fewer than two stamps).
    """
    if not is_32bit(np.dtype(dtype or "f8")) or period is None or not len(cut_ns):
        return None
    bound = CUT_PERIODS * period * 1e9
    if not (np.all(cut_ns <= bound) and np.any(plain_ns > bound)):
        return None
    worst = float(plain_ns.max()) * 1e-9
    return (
        f"PointCloud2 time field '{name}' ({dtype}) holds each sweep's stamp cut to its "
        f"lowest 32 bits, not offsets from it: its values lie within "
        f"{float(cut_ns.max()) * 1e-9:.3g} s of the stamps taken modulo 2^32 ns, but read as "
        f"offsets put a point {worst:.3g} s from its stamp ({period:.3g} s between messages)"
        f"; a clock of nanoseconds in 32 bits wraps every {WRAP_NS * 1e-9:.3g} s; " + ADVICE
    )
