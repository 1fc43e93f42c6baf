"""Entries of a dataset folder that name a file but are none: a symbolic link that leads
nowhere (its target moved or on a drive not mounted, or a loop), a directory, a FIFO.

``Path.is_file()`` and ``Path.exists()`` are False for a broken link, so a listing that
kept only files dropped such a scan without a word (the last epoch lost, or every later
epoch one period early without ``poses.tum``), and a ``poses.tum``, ``times.txt`` or
``rig.yaml`` behind a broken link read as absent (no reference, the default epoch times,
no rig). These checks name the entry instead; and a ``scans/`` without scan files but
with sub-folders that hold some (one per sensor, as many recorders write) is told so
(:func:`subfolders_hint`), not called empty.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from pathlib import Path

from planodom.errors import DatasetError


def broken_link(path: Path) -> str | None:
    """Why ``path`` is a symbolic link that leads nowhere (dangling, or a loop), or None."""
    if not path.is_symlink():
        return None
    try:
        os.stat(path)
    except OSError as exc:
        return f"a symbolic link that leads nowhere (-> {os.readlink(path)}: {exc.strerror})"
    return None


def not_a_file(path: Path) -> str | None:
    """Why the entry ``path`` is no regular file to read, or None when it is one."""
    if path.is_file():
        return None
    broken = broken_link(path)
    if broken:
        return broken
    if path.is_dir():
        return "a directory, not a file"
    return "not a regular file (a FIFO, socket or device?)"


def check_file_entries(entries: Iterable[Path], suffixes: Sequence[str]) -> None:
    """DatasetError naming the first of ``entries`` whose name ends in one of ``suffixes``
    (lower case) but is no regular file (in name order)."""
    for entry in sorted(entries):
        if entry.suffix.lower() in suffixes and (why := not_a_file(entry)):
            raise DatasetError(f"{entry}: {why}")


def optional_file(path: Path) -> bool:
    """Whether the optional file ``path`` is there: False without an entry of that name,
    True for a regular file, DatasetError naming it for an entry that is none."""
    if not path.exists() and not path.is_symlink():
        return False
    why = not_a_file(path)
    if why:
        raise DatasetError(f"{path}: {why}")
    return True


def subfolders_hint(directory: Path, suffixes: Sequence[str]) -> str:
    """For a ``directory`` without scan files: its sub-folders (at most 3 named) holding
    files that end in one of ``suffixes`` (lower case), as the end of the error, or ""."""
    found = []
    for sub in sorted(d for d in directory.iterdir() if d.is_dir() and d.name[0] != "."):
        count = sum(1 for f in sub.iterdir() if f.suffix.lower() in suffixes)
        found += [f"{sub.name}/ ({count})"] if count else []
    if not found:
        return ""
    return (
        f", but its sub-folder(s) {', '.join(found[:3])}{' ...' if len(found) > 3 else ''} "
        "hold scan files: a dataset reads the files in scans/ itself, one per epoch with "
        "every sensor's points in the base frame (move one folder's files there, or merge "
        "the sensors' files of each epoch)"
    )


def kitti_sequences_hint(root: Path) -> str:
    """For a KITTI odometry tree's root or its ``sequences/`` (which hold sequences, not
    scans): the sequence folders to give instead."""
    found = sorted(p.parent for p in root.glob("*/velodyne")) or sorted(
        p.parent for p in root.glob("sequences/*/velodyne")
    )
    if not found:
        return ""
    shown = ", ".join(str(p.relative_to(root)) for p in found[:3]) + (
        " ..." if len(found) > 3 else ""
    )
    return f"; it holds {len(found)} KITTI sequence folder(s) ({shown}): give one, e.g. {found[0]}"
