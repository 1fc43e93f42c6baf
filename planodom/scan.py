"""One epoch of laser points: the unit every reader, simulator and extractor passes around."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from planodom.errors import GeometryError


@dataclass(frozen=True, eq=False)
class Scan:
    """The points of one epoch, in the vehicle base frame at each point's acquisition time.

    Attributes:
        points: (N, 3) float64, metres, finite (no-return beams are dropped, not stored).
        ring: (N,) int32 scan-line id (the scanner of a 2D rig, the beam of a 3D lidar;
            points of one ring in scan order), or None when unknown.
        t: (N,) float64 seconds, acquisition time relative to the epoch's reference time,
            or None when unknown (then all points are taken as seen at the reference time).
        label: (N,) int32 id of the true surface each point lies on (simulated data only;
            -1 for none), or None.
    """

    points: np.ndarray
    ring: np.ndarray | None = None
    t: np.ndarray | None = None
    label: np.ndarray | None = None

    def __post_init__(self) -> None:
        pts = np.asarray(self.points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3:
            if pts.size == 0:
                pts = pts.reshape(0, 3)
            else:
                raise GeometryError(f"scan points: expected (N, 3), got shape {pts.shape}")
        object.__setattr__(self, "points", _owned(pts, self.points, writeable=True))
        for name, dtype in (("ring", np.int32), ("t", np.float64), ("label", np.int32)):
            value = getattr(self, name)
            if value is None:
                continue
            arr = np.asarray(value, dtype=dtype)
            arr = arr if arr.ndim == 1 else arr.reshape(-1)  # the same object: see _owned
            if len(arr) != len(pts):
                raise GeometryError(
                    f"scan field '{name}' has {len(arr)} values for {len(pts)} points"
                )
            object.__setattr__(self, name, _owned(arr, value))

    def __len__(self) -> int:
        return len(self.points)

    def subset(self, mask: np.ndarray) -> Scan:
        """The points selected by a boolean mask or index array, with their fields."""

        def pick(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None else a[mask]

        return Scan(self.points[mask], pick(self.ring), pick(self.t), pick(self.label))


def _owned(arr: np.ndarray, given: object, writeable: bool = False) -> np.ndarray:
    """``arr``, copied when it shares memory with the caller's ``given`` array, and
    read-only unless ``writeable``: a scan's arrays never change after construction,
    even when a driver refills one buffer for every message (the extraction memoises what
    it derives from a scan's arrays by their identity, :mod:`planodom.extraction.memo`).
    Points stay writeable because open3d's vectors take only writeable buffers; planodom
    never writes into them. A copy costs about 0.1 ms for 130 000 points; a read-only
    array (another scan's ring or times) is kept as it is, so the memo still knows it."""
    if isinstance(given, np.ndarray) and given.flags.writeable and np.shares_memory(arr, given):
        arr = arr.copy()  # another scan's read-only field is shared as it is
    if not writeable:
        arr.flags.writeable = False
    return arr


class ScanSequence(Protocol):
    """A sequence of epochs as readers give them: ``len(source)``, ``source[k] -> Scan``
    and iteration (which a reader may stream in one pass)."""

    def __len__(self) -> int: ...

    def __iter__(self) -> Iterator[Scan]: ...

    def __getitem__(self, index: int, /) -> Scan: ...
