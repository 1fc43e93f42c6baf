"""2D scanners that record several echoes a beam: ``sensor_msgs/MultiEchoLaserScan``.

Multi-echo scanners (Hokuyo UTM-30LX-EW, SICK LMS1xx / 5xx in multi-echo mode) record a
``LaserEcho`` per beam in ``ranges`` (and in ``intensities``, or none there), each a
float32 ``echoes`` array, possibly empty (no echo). A beam is placed as a LaserScan's
(:mod:`planodom.datasets.bag_msgs`): angle ``angle_min + i angle_increment`` in the
sensor's x-y plane, time ``i time_increment`` after the stamp. An echo is a return by
LaserScan's test (finite, inside ``[range_min, range_max]``, not 0): a NaN, infinite,
negative or out-of-range echo is none, as a LaserScan's range would be. Which returns of
a beam are read is :attr:`~planodom.datasets.bag_options.BagOptions.echo`:

- ``first`` (the default): the beam's first return, the nearest surface: what Cartographer
  reads from these messages (their first echo; its public 2D bags record them), so the
  same bag gives the same points there and here. An echo before it that is no return
  (one inside ``range_min``: the scanner's own window, dust at the aperture) is passed;
- ``last``: its last return (the hard surface behind glass, foliage or rain: the return
  a multi-return cloud keeps, :mod:`planodom.datasets.returns`);
- ``strongest``: its return of the largest intensity (the first of equals; the first
  return for a beam without intensities);
- ``all``: every return, each a point at its beam's angle and time.

A message whose ``intensities`` do not match its ``ranges`` (another beam count, or a
beam with intensities for another number of echoes) is refused: which echo an intensity
belongs to is unknown.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from planodom.datasets.bag_beams import beam_returns, place_beams

MULTI_ECHO = "sensor_msgs/msg/MultiEchoLaserScan"
#: The values of ``BagOptions.echo``: which returns of a beam are read (module docstring).
ECHO_MODES = ("first", "last", "strongest", "all")


def _flat(echoes: Any) -> tuple[np.ndarray, np.ndarray]:
    """A message's ``LaserEcho`` list as its echoes (m,) float64 in beam order and the
    echo count (n,) of each of its n beams."""
    arrays = [np.asarray(e.echoes, dtype=np.float64).reshape(-1) for e in echoes]
    counts = np.array([len(a) for a in arrays], dtype=np.int64)
    return (np.concatenate(arrays) if len(arrays) else np.zeros(0)), counts


def echo_arrays(msg: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A MultiEchoLaserScan's echoes: ``(ranges (m,), beam (m,) int64, intensity (m,))``,
    float64, in beam order then echo order; an intensity is NaN where the beam has none.

    Raises:
        ValueError: intensities that do not match the ranges (module docstring).
    """
    ranges, counts = _flat(msg.ranges)
    beam = np.repeat(np.arange(len(counts), dtype=np.int64), counts)
    intensity = np.full(len(ranges), np.nan)
    if len(msg.intensities) == 0:
        return ranges, beam, intensity
    if len(msg.intensities) != len(counts):
        raise ValueError(f"ranges of {len(counts)} beams but intensities of {len(msg.intensities)}")
    values, given = _flat(msg.intensities)
    odd = np.flatnonzero((given != 0) & (given != counts))
    if len(odd):
        i = int(odd[0])
        raise ValueError(
            f"beam {i} has {int(counts[i])} range echoes but {int(given[i])} intensities "
            f"({len(odd)} such beams): which echo an intensity belongs to is unknown"
        )
    has = np.repeat(given != 0, counts)
    intensity[has] = values
    return ranges, beam, intensity


def chosen_echoes(
    beam: np.ndarray, intensity: np.ndarray, valid: np.ndarray, echo: str
) -> np.ndarray:
    """Indices into the echoes of the returns read for ``echo`` (:data:`ECHO_MODES`):
    ``beam`` (m,) the beam of each echo (ascending), ``valid`` (m,) bool its returns."""
    index = np.flatnonzero(valid)
    if echo == "all" or len(index) == 0:
        return index
    b = beam[index]
    starts = np.r_[True, b[1:] != b[:-1]]
    if echo == "first":
        return index[starts]
    if echo == "last":
        return index[np.r_[starts[1:], True]]
    if echo != "strongest":
        raise ValueError(f"echo must be one of {', '.join(ECHO_MODES)}, got {echo!r}")
    key = np.nan_to_num(intensity[index], nan=-np.inf)  # a beam without: its first
    order = np.lexsort((np.arange(len(index)), -key, b))
    return index[order][np.r_[True, b[order][1:] != b[order][:-1]]]


def decode_multi_echo(msg: Any, echo: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """A MultiEchoLaserScan's returns chosen by ``echo`` as ``decode_sweep`` gives a sweep:
    ``(points (k, 3), ring (k,) zeros, dt (k,) s after the stamp, 1)``."""
    ranges, beam, intensity = echo_arrays(msg)
    keep = chosen_echoes(beam, intensity, beam_returns(ranges, msg), echo)
    return place_beams(msg, ranges[keep], beam[keep].astype(np.float64))


def multi_echo_returns(msg: Any) -> tuple[int, int]:
    """A MultiEchoLaserScan's echoes that are returns, and its beams with one (a scan with
    none is blank, whichever echo is read). Raises ValueError as :func:`echo_arrays`."""
    ranges, beam, _ = echo_arrays(msg)
    valid = beam_returns(ranges, msg)
    return int(np.count_nonzero(valid)), len(np.unique(beam[valid]))
