"""Raw float32 ``.bin`` scans: KITTI's 4 values per point or nuScenes' 5, told apart by evidence.

A ``.bin`` file has no header, so its layout is not in the file:

- ``kitti``: float32 ``x y z intensity`` rows (16 bytes a point; KITTI, and most tools
  that copied it);
- ``nuscenes``: float32 ``x y z intensity ring`` rows (20 bytes a point; nuScenes'
  ``LIDAR_TOP`` files), the ring a small whole number stored as a float;
- ``xyz``: float32 ``x y z`` rows without intensity (12 bytes a point; a cloud saved with
  numpy's ``tofile``), read only when given: ``auto`` does not pick it.

A file of N points in one layout also divides into rows of the other whenever N is a
multiple of 4 (nuScenes read as KITTI) or of 5 (KITTI read as nuScenes): read so, the
columns interleave coordinates of different points, a cloud of garbage that nothing later
refuses. ``auto`` therefore takes, of the layouts the size admits, the only one whose
columns are plausible:

- nuScenes: its ring column holds whole numbers in ``0..MAX_RING`` and its intensities are
  finite and >= 0. Read from a KITTI file, that column cycles through x, y, z and intensity
  of successive points, which are not all whole numbers unless every coordinate is.
- KITTI: its intensities are finite and >= 0. Read from a nuScenes file, that column cycles
  through every column of the 5 (4 and 5 are coprime), x and y included, which are
  negative behind and beside the sensor.

When neither is plausible, a size KITTI's rows fit is read as KITTI (intensities need
not be >= 0 in every tool that writes such files; nothing points to rings), unless the
file reads as another common layout: ``x y z`` rows (its size a multiple of 12 bytes too,
and its points clearly nearer each other in file order read so, see :func:`_step`; read as
KITTI rows, the "intensity" cycles through x, y and z, negative behind, beside or below the
sensor, and the cloud was garbage nothing refused), or float64 ``x y z
intensity`` rows (see :func:`_float64_rows`). Then, and when
no layout fits, the file is refused in one line asking for the layout (``--bin-layout``).
The tests are evidence about the columns, not tuned to a recording.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal, get_args

import numpy as np

from planodom.errors import DatasetError

BinLayout = Literal["auto", "kitti", "nuscenes", "xyz"]
#: Values per point of each layout.
BIN_COLUMNS = {"kitti": 4, "nuscenes": 5, "xyz": 3}
#: The layouts ``auto`` chooses from.
AUTO_LAYOUTS = ("kitti", "nuscenes")
#: Largest coordinate (m) of a plausible float64 reading (scan_io's MAX_COORDINATE_M).
_MAX_COORDINATE_M = 1e6
#: Largest ring id a nuScenes-style file is taken to hold: lidars have at most 128 beams,
#: so a ring column beyond this is not one (a generous bound, not from data).
MAX_RING = 1023


def check_bin_layout(layout: str) -> BinLayout:
    """``layout`` if it is one of auto, kitti, nuscenes, xyz, else DatasetError naming it."""
    if layout not in get_args(BinLayout):
        raise DatasetError(f"bin layout must be auto, kitti, nuscenes or xyz, got {layout!r}")
    return layout  # type: ignore[return-value]


def read_bin(path: Path, layout: str = "auto") -> dict[str, np.ndarray]:
    """The fields of a raw float32 ``.bin`` scan: ``x y z`` and, nuScenes-style, ``ring``.

    Args:
        path: the file.
        layout: ``kitti``, ``nuscenes``, ``xyz`` or ``auto`` (see the module docstring).

    Raises:
        DatasetError: naming the file, when its size fits no layout (or not the one given),
            or ``auto`` cannot tell the layout.
    """
    layout = check_bin_layout(layout)
    raw = path.read_bytes()
    fits = [name for name in AUTO_LAYOUTS if len(raw) % (4 * BIN_COLUMNS[name]) == 0]
    if layout != "auto":
        fits = [layout] if len(raw) % (4 * BIN_COLUMNS[layout]) == 0 else []
        if layout not in fits:
            cols = BIN_COLUMNS[layout]
            raise DatasetError(
                f"{path}: .bin size {len(raw)} bytes is not a multiple of {4 * cols} "
                f"({cols} float32 values a point, --bin-layout {layout}); truncated or "
                "another layout"
            )
        return _fields(np.frombuffer(raw, dtype="<f4").reshape(-1, BIN_COLUMNS[layout]))
    if not fits:
        xyz = len(raw) % 12 == 0 and len(raw) > 0
        raise DatasetError(
            f"{path}: .bin size {len(raw)} bytes is a multiple of neither 16 (KITTI: x y z "
            "intensity) nor 20 (nuScenes: x y z intensity ring) float32 rows; truncated"
            + ("; or x y z rows without intensity (12 bytes: --bin-layout xyz)?" if xyz else "")
        )
    values = np.frombuffer(raw, dtype="<f4")
    if len(values) == 0:  # an epoch that saw nothing, in either layout
        return _fields(values.reshape(0, 4))
    plausible = [name for name in fits if _plausible(values.reshape(-1, BIN_COLUMNS[name]))]
    if len(plausible) == 1:
        return _fields(values.reshape(-1, BIN_COLUMNS[plausible[0]]))
    others = _other_layouts(raw) if not plausible else []
    if not plausible and "kitti" in fits and not others:  # no evidence: KITTI's rows
        return _fields(values.reshape(-1, 4))
    if others:
        raise DatasetError(
            f"{path}: cannot tell the .bin layout: read as KITTI rows its intensities (every "
            f"4th float32) are negative or not finite, as {' or '.join(others)} would make "
            "them; give --bin-layout kitti if they are KITTI rows all the same"
        )
    if plausible:
        problem = "read plausibly both as KITTI and as nuScenes rows"
    else:  # rings not small whole numbers, and 16 bytes a point does not fit the size
        problem = "fit only nuScenes rows (20 bytes), whose rings are not small whole numbers"
    raise DatasetError(
        f"{path}: cannot tell the .bin layout: its {len(values)} float32 values {problem}; "
        "give --bin-layout kitti (x y z intensity) or nuscenes (x y z intensity ring)"
    )


def _other_layouts(raw: bytes) -> list[str]:
    """The other common layouts a file whose KITTI and nuScenes columns are implausible
    reads as (see the module docstring), in words."""
    out = []
    if len(raw) % 12 == 0 and len(raw) % 16 == 0:
        values = np.frombuffer(raw, dtype="<f4")
        if _step(values.reshape(-1, 3)) * 2.0 < _step(values.reshape(-1, 4)[:, :3]):
            out.append("x y z rows without intensity (12 bytes a point: --bin-layout xyz)")
    if len(raw) % 32 == 0 and _float64_rows(raw):
        out.append("float64 x y z intensity rows (32 bytes a point: convert to float32)")
    return out


def _float64_rows(raw: bytes) -> bool:
    """Whether ``raw`` holds float64 ``x y z intensity`` rows: plausible so (finite,
    coordinates within 1e6 m, intensities >= 0), while read as float32 its coordinates are
    not finite or beyond 1e6 m (refused anyway), or every other float32 is 0 (float32
    values widened to float64: their low halves); small float32 values also read as
    plausible doubles, so that alone is no evidence."""
    rows = np.frombuffer(raw, dtype="<f8").reshape(-1, 4)
    single = np.frombuffer(raw, dtype="<f4").reshape(-1, 4)[:, :3]
    with np.errstate(invalid="ignore", over="ignore"):
        if not (np.all(np.isfinite(rows)) and np.abs(rows[:, :3]).max() < _MAX_COORDINATE_M):
            return False
        broken = not np.all(np.abs(single) < _MAX_COORDINATE_M)  # NaN too
    widened = not np.any(np.frombuffer(raw, dtype="<u4")[0::2])
    return _plausible(rows) and (broken or widened)


def _step(points: np.ndarray) -> float:
    """The median distance between consecutive points (N, 3) of a reading (inf for fewer
    than two finite steps). A lidar writes its points in scan order, each near the one
    before; a reading with the wrong row length interleaves coordinates of different points
    and scatters them over the cloud's extent, so the right reading's steps are several
    times shorter (a factor 2 asks only that it be clearly so; an unordered cloud, whose
    steps are long either way, or random values give no evidence)."""
    with np.errstate(invalid="ignore", over="ignore"):
        steps = np.linalg.norm(np.diff(points.astype(np.float64), axis=0), axis=1)
    steps = steps[np.isfinite(steps)]
    return float(np.median(steps)) if len(steps) else float("inf")


def _plausible(rows: np.ndarray) -> bool:
    """Whether the columns of ``rows`` (N, 4 or 5) are those of their layout."""
    rows = rows[~np.isnan(rows[:, :3]).all(axis=1)]  # no-return points, as scan_io drops
    with np.errstate(invalid="ignore"):
        if not np.all(rows[:, 3] >= 0):  # NaN and infinities too
            return False
        if rows.shape[1] == 4:
            return bool(np.all(np.isfinite(rows[:, 3])))
        ring = rows[:, 4]
        return bool(np.all((ring >= 0) & (ring <= MAX_RING) & (ring == np.round(ring))))


def _fields(rows: np.ndarray) -> dict[str, np.ndarray]:
    fields = {"x": rows[:, 0], "y": rows[:, 1], "z": rows[:, 2]}
    if rows.shape[1] == 5:
        fields["ring"] = rows[:, 4]
    return fields
