"""The order of scan files: by name, numbers compared as numbers, a leading minus a sign.

Scan files are named by their epoch's number, often unpadded (``2.pcd`` before ``10.pcd``:
compared as text, ``10.pcd`` came first) and, for frames counted from an event, sometimes
negative (``-2.pcd``, ``-1.pcd``, ``0.pcd``: read as text and a number, ``-1`` came after
``2``). A ``-`` is a sign where it starts the name or follows a character that is neither
a letter, a digit nor another ``-`` (``scan_-1``); elsewhere it is a separator
(``frame-12``, ``2011-09-26``), as before.
"""

from __future__ import annotations

import re
from pathlib import Path

#: A number in a file name: a digit run, with a minus sign where it is one (see above).
NUMBER = re.compile(r"(?:(?<![0-9A-Za-z-])-)?\d+")
_SPLIT = re.compile(f"({NUMBER.pattern})")


def scan_order_key(path: Path) -> tuple:
    """Sort key of a scan file by its name, numbers compared as numbers: ``-1.ply`` <
    ``2.ply`` < ``10.ply`` (names without a sign sort as they always did)."""
    parts = _SPLIT.split(path.name)
    return tuple((0, int(p), p) if NUMBER.fullmatch(p) else (1, 0, p) for p in parts)


def name_numbers(name: str) -> list[int]:
    """The numbers in a file name (signed as :func:`scan_order_key` reads them)."""
    return [int(n) for n in NUMBER.findall(name)]
