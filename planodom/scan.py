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
        try:
            pts = np.asarray(self.points, dtype=np.float64)
        except (TypeError, ValueError):
            raise GeometryError(
                f"scan points: expected (N, 3) numbers, got {type(self.points).__name__}"
            ) from None
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
            arr = _int32_ids(name, value) if dtype is np.int32 else _floats(name, value)
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


#: Farthest a point may lie from the base origin and still be a sensor's return, metres.
#: The longest-range vehicle lidars reach 200 to 500 m by their data sheets (Velodyne
#: HDL-64E 120 m, Ouster OS2 240 m, Livox Tele-15 500 m); twice the longest leaves room for
#: sensors mounted off the base origin. Points beyond it are in another frame (a map-frame
#: export, a UTM offset): their planes face away from no sensor and their range-scaled
#: gaps are kilometres, so such epochs end unresolved.
MAX_RANGE_M = 1000.0


def points_beyond_range(scan: Scan, max_range_m: float = MAX_RANGE_M) -> int:
    """How many of ``scan``'s points lie more than ``max_range_m`` (m) from the base origin."""
    if len(scan) == 0:
        return 0
    return int(np.count_nonzero(np.einsum("ij,ij->i", scan.points, scan.points) > max_range_m**2))


def check_is_scan(scan: object) -> None:
    """GeometryError unless ``scan`` is a :class:`Scan` (or has its fields): an (N, 3)
    array handed over as is ended in an AttributeError deep in the extraction."""
    if not all(hasattr(scan, name) for name in ("points", "ring", "t")):
        raise GeometryError(
            f"expected a planodom.Scan, got {type(scan).__name__}; wrap (N, 3) points "
            "in metres as planodom.Scan(points) (with ring= and t= when known)"
        )


def _floats(name: str, value: object) -> np.ndarray:
    """``value`` as a float64 array (the same object when it is one already)."""
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise GeometryError(
            f"scan field '{name}': expected numbers, got {type(value).__name__}"
        ) from None


def _int32_ids(name: str, value: object) -> np.ndarray:
    """``value`` (ring or label ids) as an int32 array, the same object when it is one
    already; GeometryError for values a cast would change (0.7 truncated to ring 0, 2**32
    wrapped to 0): not whole numbers, or beyond int32. Checked only when a cast is due."""
    try:
        raw = np.asarray(value)
        if raw.dtype == np.int32:
            return raw
        if raw.dtype.kind not in "biuf":
            raise TypeError
    except (TypeError, ValueError):
        raise GeometryError(
            f"scan field '{name}': expected integer ids, got {type(value).__name__}"
        ) from None
    info = np.iinfo(np.int32)
    if raw.dtype.kind in "iu":  # a range check, no cast needed to compare
        if raw.size and (raw.min() < info.min or raw.max() > info.max):
            raise GeometryError(
                f"scan field '{name}': ids {raw.min()}..{raw.max()} are beyond int32"
            )
        return raw.astype(np.int32)
    with np.errstate(invalid="ignore"):
        arr = raw.astype(np.int32)
        changed = (arr != raw).reshape(-1)
    if raw.dtype.kind == "f" and np.any(changed):
        k = int(np.flatnonzero(changed)[0])
        raise GeometryError(
            f"scan field '{name}': {np.count_nonzero(changed)} values are not int32 "
            f"integers (first: {raw.reshape(-1)[k]!s} at point {k})"
        )
    return arr


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
