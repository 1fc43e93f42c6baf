"""Notes on a dataset whose scans are not deskewed although they may carry times: the
first scan file's fields, as :mod:`planodom.datasets.bag_time_notes` does for a bag's
clouds (a time field under a name not read, or one time for all the points)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from planodom.datasets.bag_time_notes import time_like_fields
from planodom.datasets.pcd import read_pcd
from planodom.datasets.ply import read_ply_vertices
from planodom.datasets.scan_io import TIME_FIELDS, time_field_name
from planodom.errors import DatasetError

_READERS = {".ply": read_ply_vertices, ".pcd": read_pcd}


def scan_time_notes(files: Sequence[Path], time_field: str = "auto") -> list[str]:
    """One line each, naming the first scan file: it has no time field read (``auto``) but
    fields whose names say they may hold times; or its time field holds one value for
    all its points (two or more). [] when neither, or the file is not read here (``.bin``,
    unreadable: reading the scan itself says what is wrong)."""
    if not files or time_field == "none" or files[0].suffix.lower() not in _READERS:
        return []
    first = files[0]
    try:
        fields = _READERS[first.suffix.lower()](first)
        name = time_field_name(tuple(fields), time_field)
    except (DatasetError, OSError, ValueError):
        return []
    if name is None:
        like = time_like_fields([(n, np.asarray(v).dtype.name) for n, v in fields.items()])
        if not like:
            return []
        shown = ", ".join(f"'{n}' ({d})" for n, d in like.items())
        return [
            f"{first}: none of the time fields read ({', '.join(TIME_FIELDS)}) but {shown}: "
            f"the scans are not deskewed; if one holds each point's time, --time-field "
            f"{next(iter(like))} reads it"
        ]
    values = np.asarray(fields[name]).reshape(-1)
    if len(values) > 1 and np.all(values == values[0]):
        return [
            f"{first}: time field '{name}' ({values.dtype.name}) holds one value for all "
            "its points: the scan is taken at one instant, not deskewed (a tool that "
            "wrote no per-point time?)"
        ]
    return []
