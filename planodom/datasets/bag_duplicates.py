"""The scan messages of a bag recorded twice: same topic, stamp and content (merged or
overlapping recordings), found by a digest of their serialized content."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader


def _digest(raw: bytes, ros1: bool) -> int:
    """A 64-bit digest of a scan message's serialized content. A ROS 1 message starts with
    its header's ``seq`` (4 bytes), a publisher's counter, not content: it is left out."""
    body = memoryview(raw)[4:] if ros1 else raw
    return int.from_bytes(hashlib.blake2b(body, digest_size=8).digest(), "little", signed=True)


def duplicate_sweeps(
    reader: AnyReader, path: Path, topic_of: dict[str, int], table: np.ndarray
) -> np.ndarray:
    """(n,) bool, the sweeps of ``table`` (topic, bag time, stamp per row, in bag order)
    repeating an earlier one's topic, stamp and content (the first is not one). Only rows
    sharing a topic and stamp are read again, for their content's digest: usually none."""
    n = len(table)
    duplicate = np.zeros(n, dtype=bool)
    order = np.lexsort((np.arange(n), table[:, 2], table[:, 0]))
    key = table[order][:, [0, 2]]
    same = np.flatnonzero(np.all(key[1:] == key[:-1], axis=1))
    if not len(same):
        return duplicate
    suspects = np.union1d(order[same], order[same + 1])  # ascending: bag order
    at = {(int(table[s, 0]), int(table[s, 1])) for s in suspects}
    rows_at: dict[tuple[int, int], list[int]] = {}
    for s in range(n):  # every row of those (topic, bag time): the messages come in row order
        if (k := (int(table[s, 0]), int(table[s, 1]))) in at:
            rows_at.setdefault(k, []).append(s)
    digest: dict[int, int] = {}
    from planodom.datasets.bag_index import bag_errors  # (imports this module)

    conns = [c for c in reader.connections if c.topic in topic_of]
    with bag_errors(path):
        for conn, bag_time, raw in reader.messages(connections=conns):
            waiting = rows_at.get((topic_of[conn.topic], bag_time))
            if waiting:
                digest[waiting.pop(0)] = _digest(raw, ros1=not reader.is2)
    seen: set[tuple[int, int, int]] = set()
    for s in suspects:
        if s not in digest:  # pragma: no cover - every suspect is read again
            continue
        content = (int(table[s, 0]), int(table[s, 2]), digest[s])
        duplicate[s] = content in seen
        seen.add(content)
    return duplicate
