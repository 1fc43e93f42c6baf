"""One scan file to and from a :class:`~planodom.scan.Scan`: ``.ply``, ``.pcd``, KITTI ``.bin``.

Stored per point: ``x y z`` (float32 or float64, metres), optional ``ring`` (int32),
``t`` (float64, seconds from the epoch's reference time) and ``label`` (int32). Other
properties (intensity, colour, ...) are ignored on reading. Files saved by other tools
name these fields as the lidar drivers do: the ring may be ``ring``, ``line`` (Livox) or
``channel`` (nebula), of any integer type; the time ``t``, ``time`` (Velodyne),
``timestamp``, ``offset_time`` (Livox) or ``time_stamp`` (nebula), first present wins, in
seconds when a float and in nanoseconds when an integer (Ouster's ``t``, Livox's
``offset_time``), as in a ROS PointCloud2 (:mod:`planodom.datasets.bag_msgs`).

Point times are offsets from the epoch's reference time, or absolute: Unix times (seconds
as float64, nanoseconds as float64 or a 64-bit integer) between :data:`UNIX_TIME_RANGE_S`,
as some drivers write them. Absolute times are made relative to the epoch's reference time
when that is a Unix time too (the dataset's ``poses.tum`` / ``times.txt`` on the points'
clock; more than ``MAX_SWEEP_OFFSET_S`` away is another clock and refused), else to the
scan's earliest point (epoch times counted from 0: the sweep starts at its epoch's time,
as a driver stamps it). Absolute times in float32 (128 s resolution today) are refused, as
are times that are neither offsets within ``MAX_POINT_TIME_S`` nor Unix times, and
absolute times that are all whole seconds (written with too few digits: open3d's ASCII
PCD keeps 10 significant digits, which rounds a Unix time to the second). Times on a 0.1
s or 0.01 s grid are kept (a simulator's per-sweep stamps look the same as rounded ones).
Points whose three coordinates are all NaN, or all exactly 0 (the origin, no lidar's
return), are the no-return markers of an organised cloud (PCL's, Ouster's) and are
dropped; any other non-finite coordinate is an error. ``.bin`` files hold
float32 ``x y z intensity`` rows (KITTI) or ``x y z intensity ring`` rows (nuScenes), told
apart by :mod:`planodom.datasets.bin_scan`; points are taken as they are (in the scanner
frame, which for KITTI is the base frame used here).

- PLY goes through :mod:`planodom.datasets.ply` (see there why not open3d).
- PCD goes through :mod:`planodom.datasets.pcd` (see there why not open3d).

Every value is checked after reading, so that a file never yields a scan the pipeline
would choke on later without naming the file: coordinates finite and within
``MAX_COORDINATE_M``, point times finite and within ``MAX_POINT_TIME_S`` of the epoch's
reference time, ``ring`` ids and labels integers that fit int32, rings >= 0.

Multi-return clouds (two or three points per beam firing, or a ``return_type`` field) keep
the last return of each firing (:mod:`planodom.datasets.returns`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from planodom.datasets.bag_time_units import unit_of
from planodom.datasets.bin_scan import read_bin
from planodom.datasets.pcd import read_pcd, write_pcd
from planodom.datasets.ply import read_ply_vertices, write_ply_vertices
from planodom.datasets.returns import RETURN_FIELDS, last_returns
from planodom.datasets.time_wraps import wrap_message, wraps_inside
from planodom.errors import DatasetError
from planodom.scan import Scan

#: File extensions of scan files that can be read.
SCAN_EXTENSIONS = (".ply", ".pcd", ".bin")
#: File extensions of scan files that can be written.
WRITABLE_EXTENSIONS = (".ply", ".pcd")
#: Names of the ring field in a file, first present wins.
RING_FIELDS = ("ring", "line", "channel")
#: Names of the per-point time field in a file, first present wins.
TIME_FIELDS = ("t", "time", "timestamp", "offset_time", "time_stamp")
#: Optional per-point fields and their dtypes in a :class:`Scan`.
OPTIONAL_FIELDS = {"ring": np.int32, "t": np.float64, "label": np.int32}
#: Largest coordinate magnitude (m) a scan file may hold; the extraction refuses larger
#: ones too (``planodom.extraction.pipeline.MAX_COORDINATE_M``), but without the file.
MAX_COORDINATE_M = 1e6
#: Largest point time (s) from the epoch's reference time: an epoch lasts a fraction of a
#: second; larger values are absolute timestamps or a unit error, which deskewing would
#: turn into nonsense.
MAX_POINT_TIME_S = 3600.0
#: Point times (s) read as absolute Unix times: 1973-03 to 2103-02. Offsets are below
#: MAX_POINT_TIME_S, so nothing is both; values between are refused.
UNIX_TIME_RANGE_S = (1e8, 4.2e9)
#: Largest distance (s) of absolute point times from their epoch's (absolute) reference time,
#: as for bags (:data:`planodom.datasets.bag_msgs.MAX_SWEEP_OFFSET_S`).
MAX_SWEEP_OFFSET_S = 10.0


def check_time_field(time_field: str) -> str:
    """``time_field`` (``auto``, ``none`` or a field name), or DatasetError naming it."""
    if not (isinstance(time_field, str) and time_field.strip()):
        raise DatasetError(f"time field must be auto, none or a field name, got {time_field!r}")
    return time_field


def read_scan(
    file: str | Path,
    bin_layout: str = "auto",
    reference_time: float | None = None,
    time_field: str = "auto",
    time_scale: float | None = None,
) -> Scan:
    """Read one scan file (``.ply``, ``.pcd`` or a KITTI / nuScenes ``.bin``).

    Args:
        file: the scan file; its extension picks the format.
        bin_layout: ``.bin`` files only: ``kitti``, ``nuscenes`` or ``auto`` (from the
            file's size and columns, :func:`planodom.datasets.bin_scan.read_bin`).
        reference_time: the epoch's reference time, s, which absolute point times are
            made relative to when it is a Unix time too (see the module docstring).
        time_field: the per-point time field: ``auto`` (the first of :data:`TIME_FIELDS`
            present), ``none`` (ignore the file's point times: a driver's clock that is not
            the epochs', or times nobody trusts) or a field name the file must have.
        time_scale: seconds per unit of integer time offsets (None: nanoseconds; a
            dataset's unit, :mod:`planodom.datasets.scan_time_units`).

    Returns:
        A :class:`Scan`: points (N, 3) float64 (float32 files widened exactly), with
        ``ring`` / ``t`` / ``label`` when the file has them. N may be 0.

    Raises:
        DatasetError: naming the file, when it is missing, has an unknown extension,
            does not parse, is truncated or has NaN / infinite coordinates or times,
            or is a ``.bin`` of a layout ``auto`` cannot tell; or has no field
            ``time_field``.
    """
    path = Path(file)
    check_time_field(time_field)
    suffix = _suffix(path, SCAN_EXTENSIONS, "unknown scan file extension")
    if not path.is_file():
        raise DatasetError(f"{path}: scan file does not exist")
    if suffix != ".bin" and path.stat().st_size == 0:  # a .bin of 0 bytes is 0 points
        raise DatasetError(
            f"{path}: empty file (0 bytes), no {suffix[1:].upper()} header (a write cut short?)"
        )
    try:
        if suffix == ".bin":
            fields = read_bin(path, bin_layout)
        else:
            fields = {".ply": read_ply_vertices, ".pcd": read_pcd}[suffix](path)
    except OSError as exc:
        raise DatasetError(f"{path}: cannot read scan file ({exc.strerror})") from None
    return _scan_from_fields(path, fields, reference_time, time_field, time_scale)


def write_scan(file: str | Path, scan: Scan, points_dtype: type[np.floating] = np.float64) -> None:
    """Write ``scan`` to a ``.ply`` or ``.pcd`` file, losslessly.

    Args:
        file: destination; its extension picks the format.
        scan: the scan; its optional fields are written when not None.
        points_dtype: np.float64 (exact) or np.float32 (half the size; reading widens it back
            exactly, so a float32 file round-trips bit for bit).
    """
    path = Path(file)
    suffix = _suffix(path, WRITABLE_EXTENSIONS, "cannot write scans as")
    if np.dtype(points_dtype) not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise DatasetError(f"{path}: points_dtype must be float32 or float64, not {points_dtype}")
    with np.errstate(over="ignore"):
        pts = scan.points.astype(points_dtype)
    if not np.all(np.isfinite(pts)):
        raise DatasetError(
            f"{path}: cannot write non-finite coordinates "
            f"(or beyond {np.dtype(points_dtype)} range)"
        )
    fields = {"x": pts[:, 0], "y": pts[:, 1], "z": pts[:, 2]}
    for name in OPTIONAL_FIELDS:
        value = getattr(scan, name)
        if value is not None:
            fields[name] = value
    if suffix == ".ply":
        write_ply_vertices(path, fields)
    else:
        write_pcd(path, fields)


def _suffix(path: Path, allowed: tuple[str, ...], problem: str) -> str:
    """The lower-case extension of ``path``, or DatasetError ``path: problem '.ext'``."""
    suffix = path.suffix.lower()
    if suffix not in allowed:
        raise DatasetError(
            f"{path}: {problem} '{path.suffix}' (expected one of {', '.join(allowed)})"
        )
    return suffix


def _scan_from_fields(
    path: Path,
    fields: dict[str, np.ndarray],
    reference_time: float | None = None,
    time_field: str = "auto",
    time_scale: float | None = None,
) -> Scan:
    missing = [c for c in "xyz" if c not in fields]
    if missing:
        raise DatasetError(f"{path}: no '{' '.join(missing)}' coordinates in the file")
    problem = integer_coordinates({c: (fields[c].dtype,) for c in "xyz"})
    if problem:
        raise DatasetError(f"{path}: {problem}")
    with np.errstate(invalid="ignore"):  # signalling NaNs of a corrupt file
        points = np.column_stack([fields[c].astype(np.float64) for c in "xyz"]).reshape(-1, 3)
    # no returns: PCL's all three NaN, and the origin (0, 0, 0) of organised clouds
    returned = ~np.isnan(points).all(axis=1) & (points != 0.0).any(axis=1)
    if not returned.all():
        points = points[returned]
        fields = {name: values[returned] for name, values in fields.items()}
    bad = int(np.count_nonzero(~np.isfinite(points).all(axis=1)))
    if bad:
        raise DatasetError(
            f"{path}: {bad} of {len(points)} points have NaN or infinite coordinates"
        )
    if len(points) and np.abs(points).max() > MAX_COORDINATE_M:
        raise DatasetError(
            f"{path}: coordinates reach {np.abs(points).max():.3g} m, "
            f"beyond {MAX_COORDINATE_M:g} m (not metres, or corrupt)"
        )
    extra = {}
    try:
        time_name = time_field_name(tuple(fields), time_field)
    except ValueError as exc:
        raise DatasetError(f"{path}: {exc}; --time-field auto or none") from None
    if time_name is not None:
        raw = fields[time_name]
        extra["t"] = point_times(path, time_name, raw, reference_time, time_scale)
    ring_name = next((n for n in RING_FIELDS if n in fields), None)
    if ring_name is not None:
        extra["ring"] = _int32(path, ring_name, fields[ring_name], 0)
    if "label" in fields:
        extra["label"] = _int32(path, "label", fields["label"], None)
    return_name = next((n for n in RETURN_FIELDS if n in fields), None)
    keep = last_returns(
        points,
        extra.get("ring"),
        fields[time_name] if time_name is not None else None,
        fields[return_name] if return_name is not None else None,
    )
    if keep is not None:  # a multi-return cloud: the last return of each beam firing
        return Scan(points[keep], **{name: values[keep] for name, values in extra.items()})
    return Scan(points, **extra)


def integer_coordinates(fields: Mapping[str, Any] | None) -> str | None:
    """Why coordinates ``x y z`` of these fields (``{name: (dtype, ...)}``, as numpy's
    ``dtype.fields``) cannot be read as metres, or None: integer types carry a scale the
    file does not state (millimetres? a driver's fixed point?), and a ``uchar x`` is no
    metre at all; read as metres they gave a cloud of garbage that nothing refused."""
    kinds = {c: np.dtype(fields[c][0]) for c in "xyz" if fields and c in fields}
    ints = [c for c, dtype in kinds.items() if dtype.kind not in "f"]
    if not ints:
        return None
    return (
        f"coordinate field '{ints[0]}' is {kinds[ints[0]]}, not a float: planodom reads x y "
        "z as float32 or float64 metres (convert integer coordinates with their scale)"
    )


def time_field_name(names: Sequence[str], time_field: str) -> str | None:
    """The field of ``names`` read as point times for ``time_field`` (``auto``: the first
    of :data:`TIME_FIELDS` present, ``none``: None, else that name), or None; ValueError
    ``no time field ...`` when a named field is absent (the caller names the cloud)."""
    if time_field == "none":
        return None
    if time_field == "auto":
        return next((n for n in TIME_FIELDS if n in names), None)
    if time_field not in names:
        raise ValueError(f"no time field '{time_field}' (fields: {', '.join(names)})")
    return time_field


def _int32(path: Path, name: str, values: np.ndarray, lowest: int | None) -> np.ndarray:
    """An integer field as int32, or DatasetError when a value is not an int32 integer."""
    info = np.iinfo(np.int32)
    low = info.min if lowest is None else lowest
    with np.errstate(invalid="ignore"):
        whole = values.dtype.kind in "iu" or bool(np.all(np.mod(values, 1) == 0))
    if len(values) and (not whole or values.min() < low or values.max() > info.max):
        raise DatasetError(
            f"{path}: field '{name}' must hold integers in {low}..{info.max}, "
            f"got values in {values.min()}..{values.max()}"
        )
    return values.astype(np.int32)


def point_times(
    path: Path,
    name: str,
    raw: np.ndarray,
    reference_time: float | None = None,
    time_scale: float | None = None,
) -> np.ndarray:
    """(N,) float64 seconds from the epoch's reference time, from a file's time field ``raw``
    (offsets or absolute Unix times, see the module docstring; ``time_scale``: seconds per
    unit of integer offsets, None: nanoseconds).

    Raises:
        DatasetError: naming the file and the field, for times that are NaN, neither
            offsets nor Unix times, absolute in float32, or absolute on another clock than
            the epoch's.
    """
    integer = raw.dtype.kind in "iu"
    if wraps_inside(raw):  # a clock's nanoseconds cut to 32 bits (time_wraps)
        raise DatasetError(f"{path}: {wrap_message(name, raw)}")
    scale = (1e-9 if time_scale is None else time_scale) if integer else 1.0
    unit = (unit_of(scale) or "s") if integer else "s"
    absolute = _absolute_ns(raw)
    if absolute is not None:
        if raw.dtype.itemsize < 8:
            raise DatasetError(
                f"{path}: point times '{name}' are absolute (Unix) times in {raw.dtype}, "
                "whose resolution is seconds or worse; store offsets or 64-bit values "
                "(--time-field none ignores them)"
            )
        _refuse_rounded(path, name, absolute)
        low, high = UNIX_TIME_RANGE_S
        if reference_time is None or not low <= abs(reference_time) <= high:
            return (absolute - absolute.min()).astype(np.float64) * 1e-9  # from the first
        t = (absolute - round(reference_time * 1e9)).astype(np.float64) * 1e-9
        if np.abs(t).max() > MAX_SWEEP_OFFSET_S:
            worst = float(t[np.argmax(np.abs(t))])
            raise DatasetError(
                f"{path}: absolute point times '{name}' put a point {worst:.6g} s from the "
                f"epoch's reference time {reference_time:.6f} s, beyond {MAX_SWEEP_OFFSET_S:g}"
                " s: the epoch times and the points are on different clocks (--time-field none "
                "ignores them)"
            )
        return t
    t = raw.astype(np.float64) * scale
    if not np.all(np.abs(t) <= MAX_POINT_TIME_S):  # NaN too
        bad = int(np.count_nonzero(~(np.abs(t) <= MAX_POINT_TIME_S)))
        raise DatasetError(
            f"{path}: {bad} of {len(t)} point times '{name}' (read as {unit}) are NaN, "
            f"infinite, or neither within {MAX_POINT_TIME_S:g} s of the epoch's reference "
            f"time nor Unix times ({UNIX_TIME_RANGE_S[0]:g} to {UNIX_TIME_RANGE_S[1]:g} s"
            f"{'' if integer else _float_unit_hint(t)}; --time-field none ignores them)"
        )
    return t


def _float_unit_hint(t: np.ndarray) -> str:
    """For float point times refused as seconds: the one smaller unit in which their span
    is a sweep's (5 ms to 2 s), e.g. relative nanoseconds in a float64 field."""
    finite = t[np.isfinite(t)]
    span = float(finite.max() - finite.min()) if len(finite) > 1 else 0.0
    units = [(u, span * f) for u, f in (("nanoseconds", 1e-9), ("microseconds", 1e-6))]
    fits = [(u, s) for u, s in units if 0.005 <= s <= 2.0]
    if len(fits) != 1:
        return ""
    unit, seconds = fits[0]
    return (
        f"; they span {span:.3g}, a sweep of {seconds:.3g} s in {unit}: a float time field "
        "is read as seconds, so write seconds"
    )


def _refuse_rounded(path: Path, name: str, absolute: np.ndarray) -> None:
    """DatasetError naming the file and the field when the absolute times (N,) int64 ns are
    all whole seconds (two or more points). Times all on a 0.1 s or 0.01 s grid are kept:
    they may be rounded, but a simulator's per-sweep or per-line stamps (a 2D rig's sweeps
    at 50 or 100 Hz on an exact clock) take the same few values, and refusing them would
    refuse good data."""
    advice = (
        "they have lost the sweep's timing; store offsets or binary values "
        "(--time-field none ignores them)"
    )
    if len(absolute) > 1 and not np.any(absolute % 1_000_000_000):
        raise DatasetError(
            f"{path}: absolute point times '{name}' are all whole seconds: stored with "
            "too few digits (an ASCII file's 10 significant digits, as open3d writes "
            f"them?), {advice}"
        )


def _absolute_ns(raw: np.ndarray) -> np.ndarray | None:
    """Integer nanoseconds (N,) int64 since the Unix epoch, when every value of ``raw`` is a
    Unix time (seconds as a float, nanoseconds as a float or integer); else None."""
    low, high = UNIX_TIME_RANGE_S
    if len(raw) == 0:
        return None
    if raw.dtype.kind in "iu":
        if raw.dtype.itemsize >= 4 and raw.min() >= low * 1e9 and raw.max() <= high * 1e9:
            return raw.astype(np.int64)
        return None
    with np.errstate(invalid="ignore"):
        values = raw.astype(np.float64)
        if np.all((values >= low) & (values <= high)):  # seconds; ns exact to float64's ulp
            whole = np.floor(values)
            return whole.astype(np.int64) * 1_000_000_000 + np.round((values - whole) * 1e9).astype(
                np.int64
            )
        if np.all((values >= low * 1e9) & (values <= high * 1e9)):
            return values.astype(np.int64)
    return None
