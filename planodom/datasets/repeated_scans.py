"""Scans that repeat the scan before them point for point (:class:`RepeatedScans`).

A lidar's points carry range noise, so two sweeps of a real sensor never agree to the bit,
not even at a standstill. A scan equal to its predecessor is the same frame again: a
driver that froze and kept sending its last frame with new stamps, or a recorder or a
converter that wrote one frame twice. Its epoch then measures no motion and the epoch after
it all of the motion missed (a 20-epoch simulated drive with two such scans: ATE 0.06 m ->
0.54 m, one epoch unresolved, without a word). The scans are read as they are (which of
them is the true frame is unknown) and named. A noiseless simulation standing still repeats
its scans too; the note says so.
"""

from __future__ import annotations

from planodom.scan import Scan


class RepeatedScans:
    """Consecutive epochs whose scans hold the same points, found as the epochs are read.

    Attributes:
        found: scan name -> the name of the scan before it that it repeats, in the order
            found (each scan once).
    """

    def __init__(self) -> None:
        self.found: dict[str, str] = {}
        self._last: tuple[int, str, Scan] | None = None

    def check(self, k: int, name: str, scan: Scan) -> None:
        """Take epoch ``k``'s ``scan`` (read from ``name``); compared with epoch ``k - 1``'s
        when that was the scan read before it."""
        last = self._last
        if last is not None and last[0] == k - 1 and _same_points(last[2], scan):
            self.found.setdefault(name, last[1])
        self._last = (k, name, scan)

    def note(self) -> str:
        """The warning naming the first repeat and how many there are."""
        name, before = next(iter(self.found.items()))
        return (
            f"{len(self.found)} scan(s) repeat the scan before them point for point (first: "
            f"{name}, as {before}): a driver that froze and sent its last frame again, or "
            "one frame written twice (a noiseless simulation standing still does it too)? "
            "Their epochs measure no motion and the epoch after them all of it (listed in "
            "metrics.json)"
        )


def _same_points(a: Scan, b: Scan) -> bool:
    """Whether ``a`` and ``b`` hold one or more points, the same to the bit in the same order."""
    return len(a) > 0 and a.points.shape == b.points.shape and bool((a.points == b.points).all())
