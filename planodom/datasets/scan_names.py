"""Epoch times the scan files carry: their names, when those are the clouds' stamps, or
KITTI raw's ``timestamps.txt`` beside their ``data/`` folder (:func:`kitti_raw_times`).

Tools that save a bag's clouds as files name each by its header stamp: ROS 1 ``pcl_ros``
(``bag_to_pcd``, ``pointcloud_to_pcd``) as ``SEC.NSEC.pcd`` (nanoseconds padded to nine
digits), ROS 2 ``pcl_ros`` as ``SEC_NSEC.pcd`` (not padded), others as decimal seconds
(``SEC.FRACTION``) or integer nanoseconds, often after a prefix (``cloud_``). Such a
directory has no ``times.txt``; taking its epochs 0.1 s apart would lose the clock (the
trajectory could not be compared with a reference on it) and a dropped cloud (two epochs'
motion taken as one). So when every name of a directory reads as a Unix time in one of
these forms, with one prefix, and the times increase in the files' order, they are the
epoch times (:func:`name_times`). Names that could be read two ways are not read:
``SEC.FRACTION`` with fractions of different lengths is decimal seconds (``.25``) or
unpadded nanoseconds (``.25`` = 25 ns), which differ; the note says so.
"""

from __future__ import annotations

import calendar
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from planodom.datasets.scan_io import UNIX_TIME_RANGE_S
from planodom.datasets.scan_order import name_numbers
from planodom.errors import DatasetError

#: A line of KITTI raw's ``timestamps.txt``: ``2011-09-26 13:02:25.964389445``.
_KITTI_RAW_LINE = re.compile(r"(\d{4})-(\d{2})-(\d{2}) (\d{2}):(\d{2}):(\d{2})(?:\.(\d{1,9}))?")

#: ``PREFIX SEC . FRACTION``: decimal seconds (nanoseconds when padded to nine digits).
_DECIMAL = re.compile(r"(?P<prefix>(?:.*\D)?)(?P<sec>\d{9,10})\.(?P<frac>\d{1,9})")
#: ``PREFIX SEC _ NSEC``: ROS 2 pcl_ros' seconds and nanoseconds (NSEC not padded).
_SEC_NSEC = re.compile(r"(?P<prefix>(?:.*\D)?)(?P<sec>\d{9,10})_(?P<nsec>\d{1,9})")
#: ``PREFIX NS``: integer nanoseconds since the Unix epoch.
_NANOSECONDS = re.compile(r"(?P<prefix>(?:.*\D)?)(?P<ns>\d{18,19})")


def _stem(file: Path) -> str:
    """The name without its scan extension (``.pcd``, ``.ply``, ``.bin``)."""
    return file.name[: -len(file.suffix)] if file.suffix else file.name


def name_times(files: Sequence[Path]) -> tuple[np.ndarray | None, str | None]:
    """Epoch times (E,) float64 Unix seconds from the names of ``files`` (in their order),
    and a note on how they were read; ``(None, None)`` when the names are no stamps, and
    ``(None, note)`` when they look like stamps that could be read two ways."""
    stems = [_stem(f) for f in files]
    if len(stems) < 2:
        return None, None
    forms = ((_SEC_NSEC, "SEC_NSEC"), (_NANOSECONDS, "NSEC"), (_DECIMAL, "SEC.FRACTION"))
    for pattern, form in forms:
        found = [pattern.fullmatch(s) for s in stems]
        if not all(found) or len({m["prefix"] for m in found if m}) != 1:
            continue
        matches = [m for m in found if m]
        if form == "SEC.FRACTION" and len({len(m["frac"]) for m in matches}) > 1:
            return None, (
                f"the scan file names look like stamps ({files[0].name}, ...) but their "
                "fractions have different lengths (decimal seconds or unpadded nanoseconds?): "
                "not read as times; write the epoch times to times.txt"
            )
        if form == "SEC_NSEC":
            ns = [int(m["sec"]) * 10**9 + int(m["nsec"]) for m in matches]
        elif form == "NSEC":
            ns = [int(m["ns"]) for m in matches]
        else:
            ns = [int(m["sec"]) * 10**9 + int(m["frac"].ljust(9, "0")) for m in matches]
        seconds = np.array(ns, dtype=np.int64)
        lo, hi = UNIX_TIME_RANGE_S
        if seconds.min() < lo * 1e9 or seconds.max() > hi * 1e9 or np.any(np.diff(seconds) <= 0):
            return None, None
        times = seconds.astype(np.float64) / 1e9
        return times, (
            f"epoch times from the scan file names ({form}, Unix time, {files[0].name} to "
            f"{files[-1].name}: {times[0]:.3f} to {times[-1]:.3f} s{_steps(times)})"
        )
    return None, None


def kitti_raw_times(files: Sequence[Path]) -> tuple[np.ndarray | None, str | None]:
    """Epoch times (E,) float64 s from KITTI raw's ``timestamps.txt`` beside the ``data/``
    folder of ``files`` (``velodyne_points/data/0000000000.bin``, ...: one line
    ``YYYY-MM-DD HH:MM:SS.NNNNNNNNN`` a scan, read as UTC), and a note; ``(None, None)``
    for other folders.

    Raises:
        DatasetError: naming ``timestamps.txt`` (and the line) for a line that is no such
            time, a count other than the scans', or times that do not increase.
    """
    folder = files[0].parent if files else None
    if folder is None or folder.name != "data" or not (folder.parent / "timestamps.txt").is_file():
        return None, None
    path = folder.parent / "timestamps.txt"
    ns = []
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        if not line.strip():
            continue
        found = _KITTI_RAW_LINE.fullmatch(line.strip())
        if found is None:
            raise DatasetError(
                f"{path}:{number}: expected a time 'YYYY-MM-DD HH:MM:SS.NNNNNNNNN', got {line!r}"
            )
        *fields, frac = found.groups()
        whole = calendar.timegm(tuple(int(f) for f in fields) + (0, 0, 0))
        ns.append(whole * 10**9 + int((frac or "0").ljust(9, "0")))
    if len(ns) != len(files):
        raise DatasetError(f"{path}: {len(ns)} times for {len(files)} scan files in {folder}")
    stamps = np.array(ns, dtype=np.int64)
    if np.any(np.diff(stamps) <= 0):
        k = int(np.flatnonzero(np.diff(stamps) <= 0)[0]) + 1
        raise DatasetError(f"{path}: times must increase (scan {k} is not after scan {k - 1})")
    times = stamps.astype(np.float64) / 1e9
    return times, f"epoch times from KITTI raw's {path} (read as UTC{_steps(times)})"


def _steps(times: np.ndarray) -> str:
    """The notes' ", steps ... s median, ... s largest" of epoch times (E,) s; empty for
    fewer than two."""
    steps = np.diff(times)
    if not len(steps):
        return ""
    return f", steps {np.median(steps):.3f} s median, {steps.max():.3f} s largest"


def check_numbering(files: Sequence[Path], times_file: str) -> None:
    """DatasetError at a gap in numbered scan files, when no ``times_file`` gives the times.

    Without a file of epoch times (a dataset's ``poses.tum``, a KITTI sequence's
    ``times.txt``) epoch k is taken at ``k / epoch_rate``: a missing file would make the
    motion over two epochs look like one epoch's, beyond the association's bounds or
    silently wrong. Rather than guess (e.g. times from the numbers, with bounds scaled by
    the gap), a gap is an error naming the files and ``times_file``. Files count as
    numbered when each name has a digit run and the most common step between consecutive
    numbers is 1 (names that are timestamps are not checked).
    """
    runs = [name_numbers(f.stem) for f in files]
    if len(files) < 2 or not all(runs):
        return
    numbers = np.array([r[-1] for r in runs])
    steps = np.diff(numbers)
    values, counts = np.unique(steps, return_counts=True)
    if values[np.argmax(counts)] != 1 or np.all(steps == 1):
        return
    k = int(np.flatnonzero(steps != 1)[0])
    a, b, step = files[k], files[k + 1], int(steps[k])
    problem = f"{step - 1} scan(s) missing" if step > 1 else "numbers out of order"
    raise DatasetError(
        f"{b}: follows {a.name} in the numbering ({problem}) and "
        f"there is no {times_file} to give the epoch times (they would be taken as "
        f"contiguous); add {times_file}, or renumber the scans if no epoch is missing"
    )
