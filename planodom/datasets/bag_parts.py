"""The storage files of a ROS 2 bag: which cannot be read, and a view of the others.

A split recording (``ros2 bag record --max-bag-size``: ``rec_0.db3``, ``rec_1.db3``, ...
or ``.mcap``, one ``metadata.yaml``) is read as one bag, so one broken part (missing, cut
short, overwritten) stopped the whole. :func:`broken_parts` names each such part;
:func:`readable_view` is a folder that lists only the others (their files linked, the
metadata without the broken ones), which the reader opens instead of the bag with
``BagOptions.skip_broken_parts``; :func:`missing_part_note` says which time span, and so
which epochs, are missing then.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from planodom.datasets.bag_paths import MCAP_MAGIC
from planodom.errors import DatasetError

NS = 1_000_000_000


@dataclass(frozen=True)
class BrokenPart:
    """One storage file of a ROS 2 bag that cannot be read.

    Attributes:
        path: the file. number: its place in ``relative_file_paths`` (from 1); of ``count``.
        problem: why ("is missing", "is cut short (no mcap end magic)", ...).
        span: (first, last) message time in ns from ``metadata.yaml``'s ``files``, or None.
    """

    path: Path
    number: int
    count: int
    problem: str
    span: tuple[int, int] | None = None

    def describe(self) -> str:
        """``<file>, part 2 of the 3 metadata.yaml lists, is missing``."""
        which = f"part {self.number} of the {self.count}" if self.count > 1 else "the storage file"
        return f"{self.path}, {which} metadata.yaml lists, {self.problem}"


def _metadata(path: Path) -> dict[str, Any] | None:
    try:
        meta = yaml.safe_load((path / "metadata.yaml").read_text(encoding="utf-8"))
        info = meta["rosbag2_bagfile_information"]
        [str(n) for n in info["relative_file_paths"]]
    except (OSError, yaml.YAMLError, KeyError, TypeError):
        return None
    return info if isinstance(info, dict) else None


def _span(info: dict[str, Any], name: str) -> tuple[int, int] | None:
    """A part's (first, last) message time, ns, from the metadata's ``files``."""
    for entry in info.get("files") or []:
        try:
            if Path(str(entry["path"])).name == Path(name).name:
                start = int(entry["starting_time"]["nanoseconds_since_epoch"])
                return start, start + int(entry["duration"]["nanoseconds"])
        except (KeyError, TypeError, ValueError):
            return None
    return None


def _problem(part: Path, storage: str, compressed: bool) -> str | None:
    """Why the storage file ``part`` cannot be opened, or None (it opens: its messages
    may still be damaged further in)."""
    if not part.is_file():
        return "is missing"
    if compressed:  # a whole-file zstd archive: opened only once decompressed
        return None
    if part.suffix == ".mcap":
        with open(part, "rb") as f:
            head = f.read(len(MCAP_MAGIC))
            f.seek(max(part.stat().st_size - len(MCAP_MAGIC), 0))
            tail = f.read()
        if head != MCAP_MAGIC:
            return "is not an mcap file (no mcap start magic: overwritten?)"
        if tail != MCAP_MAGIC:
            return "is cut short (no mcap end magic)"
    if storage != "sqlite3":
        return None
    from rosbags.rosbag2.storage_sqlite3 import Sqlite3Reader

    from planodom.datasets.bag_index import BAG_ERRORS  # (imports this module's callers)

    reader = Sqlite3Reader(part)
    try:
        reader.open()
    except BAG_ERRORS as exc:
        detail = " ".join(str(exc).split()).split(": ")[-1][:80]
        return f"cannot be opened as sqlite3 ({detail}: cut short or overwritten?)"
    reader.close()
    return None


def broken_parts(path: Path) -> list[BrokenPart]:
    """The storage files of the ROS 2 bag folder ``path`` that its ``metadata.yaml`` lists
    and that cannot be read: missing, an mcap file without its start or end magic (cut
    short or overwritten), a sqlite3 file that does not open. Empty when all open (or the
    metadata cannot be read: the reader says why)."""
    info = _metadata(path)
    if info is None:
        return []
    names = [str(n) for n in info["relative_file_paths"]]
    storage = str(info.get("storage_identifier", ""))
    compressed = str(info.get("compression_mode", "")).lower() == "file"
    out = []
    for k, name in enumerate(names):
        part = path / Path(name).name
        problem = _problem(part, storage, compressed)
        if problem is not None:
            out.append(BrokenPart(part, k + 1, len(names), problem, _span(info, name)))
    return out


class DamagedPartError(DatasetError):
    """A part of a split ROS 2 recording opens but cannot be read further in (``parts``:
    those found, :func:`damaged_parts`)."""

    def __init__(self, message: str, parts: list[BrokenPart]) -> None:
        super().__init__(message)
        self.parts = parts


def damaged_parts(path: Path, known: list[BrokenPart] | None = None) -> list[BrokenPart]:
    """The parts of the ROS 2 bag folder ``path`` that open but fail when read to the end
    (a corrupt mcap chunk or sqlite3 page behind valid magics and schema): each part not
    in ``known`` read alone, every message, through a :func:`readable_view` of it. Reads
    the whole bag again: called only once a reading failed."""
    info = _metadata(path)
    if info is None:
        return []
    from rosbags.highlevel import AnyReader

    from planodom.datasets.bag_index import BAG_ERRORS  # (imports this module's callers)

    names = [Path(str(n)).name for n in info["relative_file_paths"]]
    parts = [BrokenPart(path / n, k + 1, len(names), "") for k, n in enumerate(names)]
    skip = {p.path.name for p in known or []}
    out = []
    for part in parts:
        if len(parts) < 2 or part.path.name in skip or not part.path.is_file():
            continue
        view = readable_view(path, [p for p in parts if p is not part])
        try:
            with AnyReader([Path(view.name)]) as reader:
                for _ in reader.messages():
                    pass
        except BAG_ERRORS as exc:
            detail = (" ".join(str(exc).split()) or type(exc).__name__)[:80]
            problem = f"opens but cannot be read to its end ({detail}: a damaged chunk or page?)"
            out.append(
                BrokenPart(part.path, part.number, part.count, problem, _span(info, part.path.name))
            )
        finally:
            view.cleanup()
    return out


def damaged_note(broken: list[BrokenPart]) -> str:
    """The first of the ``broken`` parts of one bag, with how to read the others."""
    part = broken[0]
    rest = ""
    if part.count > len(broken):
        rest = (
            "; --skip-bad-scans reads the other parts (their epochs only), as does leaving it "
            f"out of relative_file_paths and files in {part.path.parent / 'metadata.yaml'}"
        )
    return part.describe() + rest


def readable_view(path: Path, broken: list[BrokenPart]) -> tempfile.TemporaryDirectory:
    """A temporary folder that is the bag ``path`` without its ``broken`` parts: the
    others linked (or copied where links are not allowed), ``metadata.yaml`` listing them
    only. Removed when the returned object is cleaned up or collected."""
    info = _metadata(path)
    assert info is not None  # broken parts come from a readable metadata
    left = {p.path.name for p in broken}
    view = tempfile.TemporaryDirectory(prefix="planodom-bag-")
    folder = Path(view.name)
    names = [str(n) for n in info["relative_file_paths"] if Path(str(n)).name not in left]
    for name in names:
        source = (path / Path(name).name).resolve()
        try:
            os.symlink(source, folder / Path(name).name)
        except OSError:
            import shutil

            shutil.copyfile(source, folder / Path(name).name)
    info = dict(info)
    info["relative_file_paths"] = names
    info["files"] = [
        f for f in info.get("files") or [] if Path(str(f.get("path", ""))).name not in left
    ]
    text = yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False)
    (folder / "metadata.yaml").write_text(text, encoding="utf-8")
    return view


def missing_part_note(part: BrokenPart, times: np.ndarray) -> str:
    """The note on a part left out: its time span and the epochs around it (``times``
    (E,) the epoch times read, seconds)."""
    head = f"{part.describe()}: left out (--skip-bad-scans), the other parts read"
    if part.span is None:
        return head + "; its time span is not in metadata.yaml: check the epoch times"
    a, b = part.span[0] / NS, part.span[1] / NS
    before = np.flatnonzero(times < a)
    after = np.flatnonzero(times > b)
    if not len(before) and not len(after):
        where = "no epoch is read around it"
    elif not len(before):
        where = f"the run starts at epoch 0 (t = {times[after[0]]:.3f} s), after it"
    elif not len(after):
        where = f"the run ends at epoch {before[-1]} (t = {times[before[-1]]:.3f} s), before it"
    else:
        i, j = int(before[-1]), int(after[0])
        where = (
            f"a gap between epoch {i} (t = {times[i]:.3f} s) and epoch {j} "
            f"(t = {times[j]:.3f} s), the epochs read either side"
        )
    return f"{head}; its messages from {a:.3f} to {b:.3f} s are missing: {where}"


def skipped_parts(
    path: Path, skip: bool
) -> tuple[list[BrokenPart], tempfile.TemporaryDirectory | None]:
    """With ``skip``, the broken parts of the ROS 2 bag folder ``path`` and a
    :func:`readable_view` without them (None when none is broken); ``([], None)`` without
    ``skip`` or for a ROS 1 bag. DatasetError when every part is broken."""
    if not skip or not path.is_dir():
        return [], None
    broken = broken_parts(path)
    if not broken:
        return [], None
    if len(broken) == broken[0].count:
        from planodom.errors import DatasetError

        raise DatasetError(
            f"{path}: cannot read bag: {broken[0].describe()}, as are all the others"
        )
    return broken, readable_view(path, broken)


@contextmanager
def tf_in_skipped_part(broken: list[BrokenPart]) -> Iterator[None]:
    """Add to a missing transform's DatasetError that the first part was left out: a
    ROS 2 recorder writes the latched ``/tf_static`` once, at the start, into it."""
    try:
        yield
    except DatasetError as exc:
        if not any(p.number == 1 for p in broken) or "no transform" not in str(exc):
            raise
        raise DatasetError(
            f"{exc}; part 1 of the recording, where the recorder writes /tf_static, was "
            "left out (--skip-bad-scans)"
        ) from None
