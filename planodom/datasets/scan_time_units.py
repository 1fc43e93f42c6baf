"""The unit of a dataset's integer point-time offsets in its scan files, as for bags.

PLY and PCD fields have a type but no unit: integer offsets are read as nanoseconds (as
Ouster's ``t``), but a tool may have written microseconds, which read as nanoseconds make
a 0.1 s sweep last 0.1 ms (deskewed as one instant, without a word). The rule is the bag
reader's (:mod:`planodom.datasets.bag_time_units`: each sweep votes for the reading whose
span lies nearer the period, here between the epochs' times), over the first
:data:`SAMPLE_SCANS` scans, read once when the dataset is opened. Float offsets are not
concerned: seconds that are milliseconds span a thousand epoch periods, which reading a
scan refuses with its own message.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from planodom.datasets.bag_time_units import TimeUnit, TopicTimes, choose_unit
from planodom.datasets.pcd import read_pcd
from planodom.datasets.ply import read_ply_vertices
from planodom.datasets.scan_io import UNIX_TIME_RANGE_S, time_field_name
from planodom.errors import DatasetError

#: Scans read to choose the unit: a second of a 10 Hz lidar (a judgment: enough for a
#: majority, few enough to open a dataset at once; not fitted to data).
SAMPLE_SCANS = 10
_READERS = {".ply": read_ply_vertices, ".pcd": read_pcd}


def scan_time_unit(
    files: Sequence[Path], times: np.ndarray, time_field: str = "auto"
) -> TimeUnit | None:
    """The unit of the scans' integer time offsets, or None (no such field, float or
    absolute times, ``.bin`` scans, or fewer than two epochs).

    Args:
        files: the scan files, in epoch order; times: (E,) their epoch times, s.
        time_field: ``auto``, ``none`` or a field name (as :func:`read_scan`).
    """
    if time_field == "none" or len(files) < 2:
        return None
    sample = list(files[:SAMPLE_SCANS])
    spans = TopicTimes()
    for file in sample:
        reader = _READERS.get(file.suffix.lower())
        if reader is None:
            return None
        try:
            fields = reader(file)
            name = time_field_name(tuple(fields), time_field)
        except (DatasetError, OSError, ValueError):
            continue  # reading the scan itself says what is wrong with it
        if name is None or fields[name].dtype.kind not in "iu":
            return None
        raw = fields[name]
        if len(raw) and raw.max() >= UNIX_TIME_RANGE_S[0] * 1e9:  # absolute ns: no offsets
            return None
        spans.add(name, raw)
    if not spans.name:
        return None
    stamps = np.round(np.asarray(times[: len(sample)], dtype=np.float64) * 1e9).astype(np.int64)
    return choose_unit(spans, stamps, between="epochs")
