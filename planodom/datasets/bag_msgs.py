"""Decoding the messages of a bag: sweeps (LaserScan, PointCloud2) and reference poses.

A sweep is decoded in its sensor's frame (the message's ``header.frame_id``): points (n, 3)
float64 metres, the ring of each point within the sensor (0 for a LaserScan), and each
point's time (n,) float64 seconds relative to the message's ``header.stamp``.

- ``sensor_msgs/LaserScan``: beam ``i`` at angle ``angle_min + i angle_increment`` in the
  sensor's x-y plane, seen at ``i time_increment`` after the stamp (the ROS convention:
  the stamp is the first beam's time). Beams with a non-finite range, one outside
  ``[range_min, range_max]`` or 0 (a driver's "no echo" beside a ``range_min`` of 0) are
  no returns and are dropped. A ``MultiEchoLaserScan``'s beams likewise, with the echoes
  of each that ``echo`` chooses (:mod:`planodom.datasets.bag_multiecho`).
- ``sensor_msgs/PointCloud2``: fields ``x y z`` (float32/float64); an optional ring field
  (:data:`RING_FIELDS`) and time field (:data:`~planodom.datasets.scan_io.TIME_FIELDS`,
  first present wins). A ring id of its integer field's largest value (65535 in a uint16)
  is a driver's "no ring": its point is left out (and noted; negative and stray ids are
  left out over a whole topic, :mod:`planodom.datasets.bag_rings`); a float ring field must
  hold whole ids, and a field that is read must not be given twice with two layouts (each
  refused otherwise). Integer
  time fields are nanoseconds, float ones seconds (offsets: unless a topic's sweeps span
  its period between messages as microseconds / milliseconds instead,
  :mod:`planodom.datasets.bag_time_units`); values above 1e15 ns / 1e8 s are absolute
  times (since the Unix epoch), smaller ones offsets from the stamp; float values above
  1e15 are absolute nanoseconds (livox_ros_driver2 stores its ``timestamp`` as a double of
  nanoseconds). A sweep whose times then lie more than :data:`MAX_SWEEP_OFFSET_S` from its
  stamp is refused: its field is in a unit these rules do not cover; so is a topic whose
  sweeps lie more than two periods from their stamps, or absolute times in a float32
  (:mod:`planodom.datasets.bag_clock`). Points with a
  non-finite coordinate or exactly at the origin (a common no-return marker) are dropped.
  A multi-return cloud keeps the last return of each beam firing
  (:mod:`planodom.datasets.returns`).
- Livox's ``CustomMsg`` (:mod:`planodom.datasets.bag_livox`): ring ``line``, times from
  ``timebase`` and ``offset_time``; a point its ``tag`` marks as high confidence noise is
  left out, in a PointCloud2 with Livox's ``tag`` and ``line`` fields too.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from planodom.datasets.bag_beams import beam_returns, place_beams
from planodom.datasets.bag_clock import check_absolute_type
from planodom.datasets.bag_livox import LIVOX_CUSTOM, decode_livox, livox_noise
from planodom.datasets.bag_multiecho import MULTI_ECHO, decode_multi_echo, multi_echo_returns
from planodom.datasets.bag_tf import frame_name, transform_from_msg
from planodom.datasets.bag_time_units import UNIT_WORDS, time_key, unit_of
from planodom.datasets.returns import RETURN_FIELDS, last_returns
from planodom.datasets.scan_io import integer_coordinates, time_field_name
from planodom.datasets.time_wraps import wrap_message, wraps_inside

LASER_SCAN = "sensor_msgs/msg/LaserScan"
POINT_CLOUD2 = "sensor_msgs/msg/PointCloud2"
#: The 2D scanners' messages: one ring, beams at angles (a scan without a return is normal).
LASER_TYPES = (LASER_SCAN, MULTI_ECHO)
SCAN_TYPES = (LASER_SCAN, MULTI_ECHO, POINT_CLOUD2, *LIVOX_CUSTOM)
ODOMETRY = "nav_msgs/msg/Odometry"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
POSE_COV_STAMPED = "geometry_msgs/msg/PoseWithCovarianceStamped"
TRANSFORM_STAMPED = "geometry_msgs/msg/TransformStamped"
POSE_TYPES = (ODOMETRY, POSE_STAMPED, POSE_COV_STAMPED, TRANSFORM_STAMPED)
TF_MESSAGE = "tf2_msgs/msg/TFMessage"

#: Names of a per-point ring (scan line) field, first present wins.
RING_FIELDS = ("ring", "line", "channel")
#: Largest per-point time (s) from a sweep's stamp: a lidar sweep lasts a fraction of a
#: second (a non-repetitive Livox integrates up to about one), and a driver stamps it at its
#: start or end; times beyond this are a unit the rules above do not cover (milliseconds,
#: microseconds, a clock of its own), which deskewing would turn into nonsense.
MAX_SWEEP_OFFSET_S = 10.0
#: PointField datatype codes -> numpy types.
POINT_FIELD_TYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


def stamp_ns(header: Any) -> int:
    """A ``std_msgs/Header``'s stamp in integer nanoseconds since the Unix epoch."""
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def decode_sweep(
    msg: Any,
    msgtype: str,
    time_field: str = "auto",
    time_scales: Mapping[tuple[str, str], float] | None = None,
    echo: str = "first",
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, int]:
    """One sweep in its sensor frame: ``(points (n, 3), ring (n,) int32 or None, dt (n,), rings)``.

    ``dt`` is float64 seconds after ``header.stamp``; ``rings`` the ring count (1 for a
    LaserScan, max ring + 1 for a cloud with a ring field, 0 without one). ``time_field``
    (:class:`~planodom.datasets.bag_options.BagOptions`): ``"auto"``, ``"none"`` (every
    point at the stamp) or the name of a cloud's time field. ``time_scales``: seconds per
    unit of a cloud's time offsets by time field (``time_key``: name and kind,
    :mod:`planodom.datasets.bag_time_units`); a field without one (or None): the
    documented reading, integers ns and floats s. ``echo``: a MultiEchoLaserScan's
    returns read (:mod:`planodom.datasets.bag_multiecho`).

    Raises:
        ValueError: a malformed message (one line, the caller adds the topic).
    """
    with np.errstate(invalid="ignore", over="ignore"):  # corrupt or signalling-NaN values
        if msgtype == LASER_SCAN:
            return _decode_laser_scan(msg)
        if msgtype == MULTI_ECHO:
            return decode_multi_echo(msg, echo)
        if msgtype == POINT_CLOUD2:
            return _decode_cloud(msg, time_field, time_scales)
        if msgtype in LIVOX_CUSTOM:
            points, ring, dt, rings = decode_livox(msg, stamp_ns(msg.header))
            return points, ring, np.zeros_like(dt) if time_field == "none" else dt, rings
    raise ValueError(f"{msgtype} is not a scan message")


def _laser_scan_valid(msg: Any) -> np.ndarray:
    """(n,) bool, the LaserScan's ranges that are returns: finite, in its range limits."""
    return beam_returns(np.asarray(msg.ranges, dtype=np.float64), msg)


def laser_scan_returns(msg: Any, msgtype: str = LASER_SCAN, sweep: int | None = None) -> int:
    """The number of returns of a ``sensor_msgs/LaserScan`` (the points it decodes to), or
    of a ``MultiEchoLaserScan`` (its echoes that are returns; ``sweep``: its ordinal in
    its topic, for the errors).

    Raises:
        ValueError: a scan with returns whose beam angles or times cannot be placed: a
            non-finite ``angle_min``, ``angle_increment``, ``time_increment`` or
            ``range_min``, or an ``angle_increment`` of 0 under several beams (all on one
            ray); a MultiEchoLaserScan's intensities that do not match its ranges.
    """
    what = "LaserScan"
    if msgtype == MULTI_ECHO:
        what = f"MultiEchoLaserScan (message {sweep} of the topic, from 0)"
        try:
            returns, lit = multi_echo_returns(msg)
        except ValueError as exc:
            raise ValueError(f"{what} stamped {stamp_ns(msg.header) / 1e9:.3f} s: {exc}") from None
    else:
        returns = lit = int(np.count_nonzero(_laser_scan_valid(msg)))
    bad = [
        f"{name} {value}"
        for name in ("angle_min", "angle_increment", "time_increment", "range_min")
        if not np.isfinite(value := float(getattr(msg, name)))
    ]
    if not bad and float(msg.angle_increment) == 0.0 and lit > 1:
        bad = ["angle_increment 0 under several beams"]
    if bad and (returns or not np.isfinite(float(msg.range_min))):
        raise ValueError(
            f"{what} stamped {stamp_ns(msg.header) / 1e9:.3f} s has {', '.join(bad)}: its "
            "beams cannot be placed (a damaged message or a driver's bug)"
        )
    return returns


def _decode_laser_scan(msg: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    ranges = np.asarray(msg.ranges, dtype=np.float64)
    valid = _laser_scan_valid(msg)
    return place_beams(msg, ranges[valid], np.flatnonzero(valid).astype(np.float64))


def _cloud_array(msg: Any) -> tuple[np.ndarray, dict[str, str]]:
    """The points of a PointCloud2 as a flat structured array (only the known fields, the
    first of a name) and the names given twice with another layout (name -> both)."""
    order = ">" if msg.is_bigendian else "<"
    names, formats, offsets = [], [], []
    seen: dict[str, str] = {}
    twice: dict[str, str] = {}
    for f in msg.fields:
        code = POINT_FIELD_TYPES.get(int(f.datatype))
        if code is None:
            continue
        layout = f"{np.dtype(code).name} at offset {int(f.offset)}" + (
            f" count {int(f.count)}" if int(f.count) > 1 else ""
        )
        if f.name in seen:
            if layout != seen[f.name] and f.name not in twice:
                twice[f.name] = f"{seen[f.name]} and {layout}"
            continue
        seen[f.name] = layout
        names.append(f.name)
        formats.append(order + code if int(f.count) <= 1 else (order + code, int(f.count)))
        offsets.append(int(f.offset))
    step, width, height = int(msg.point_step), int(msg.width), int(msg.height)
    for name, form, offset in zip(names, formats, offsets, strict=True):
        size = np.dtype(form).itemsize
        if offset < 0 or offset + size > step:
            raise ValueError(
                f"PointCloud2 field '{name}' ({size} bytes at offset {offset}) does not fit "
                f"its point_step of {step} bytes"
            )
    dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": step})
    data = np.asarray(msg.data, dtype=np.uint8).reshape(-1)
    row_step = int(msg.row_step) if int(msg.row_step) > 0 else width * step
    if width * height == 0:
        return np.zeros(0, dtype=dtype), twice
    if step <= 0 or row_step < width * step or len(data) < row_step * (height - 1) + width * step:
        raise ValueError(
            f"PointCloud2 of {height}x{width} points with point_step {step} and row_step "
            f"{row_step} does not fit its {len(data)} data bytes"
        )
    rows = [
        np.frombuffer(data[r * row_step : r * row_step + width * step].tobytes(), dtype=dtype)
        for r in range(height)
    ]
    return (rows[0] if height == 1 else np.concatenate(rows)), twice


def _ring_ids(values: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
    """A ring field's values (n,) as int64 ids and a mask (n,) of its "no ring" points:
    the largest value of an integer field's type (65535 in a uint16 field), which drivers
    write for a point of no scan line and which would otherwise count as that many rings.

    Raises:
        ValueError: a float field holding a fraction or a non-finite value (not a ring
            id; it was truncated).
    """
    if values.dtype.kind == "f":
        bad = ~np.isfinite(values) | (values != np.floor(values))
        if bad.any():
            raise ValueError(
                f"PointCloud2 ring field '{name}' ({values.dtype.name}) holds "
                f"{values[bad][0]:g} at {int(bad.sum())} of {len(values)} points, not a "
                "whole ring id"
            )
        return values.astype(np.int64), np.zeros(len(values), dtype=bool)
    ids = values.astype(np.int64)  # negative ids: left out over the topic (bag_rings)
    return ids, ids == np.iinfo(values.dtype).max


def _cloud_parts(
    msg: Any, time_field: str
) -> tuple[np.ndarray, np.ndarray | None, int, str | None, np.ndarray | None, int]:
    """A cloud's kept points (n, 3), their ring (or None), the ring count, the time field
    read (or None), its raw values (n,) at the kept points (or None) and the number of
    points left out for a "no ring" id (:func:`_ring_ids`)."""
    cloud, twice = _cloud_array(msg)
    names = cloud.dtype.names or ()
    ring_name = next((n for n in RING_FIELDS if n in names), None)
    time_name = _time_name(names, time_field)
    return_name = next((n for n in RETURN_FIELDS if n in names), None)
    for name in ("x", "y", "z", ring_name, time_name, return_name):
        if name in twice:
            raise ValueError(
                f"PointCloud2 field '{name}' given twice ({twice[name]}): which one holds "
                "its values is unknown"
            )
        if name in names and cloud.dtype.fields[name][0].shape:  # type: ignore[index]
            count = cloud.dtype.fields[name][0].shape[0]  # type: ignore[index]
            raise ValueError(f"PointCloud2 field '{name}' has count {count}, not 1 value a point")
    missing = [c for c in "xyz" if c not in names]
    if missing:
        raise ValueError(f"PointCloud2 without field(s) {', '.join(missing)}")
    problem = integer_coordinates(cloud.dtype.fields)
    if problem:
        raise ValueError(f"PointCloud2 {problem}")
    points = np.column_stack([cloud[c].astype(np.float64) for c in "xyz"])
    valid = np.all(np.isfinite(points), axis=1) & np.any(points != 0.0, axis=1)
    if "tag" in names and "line" in names:  # Livox's layout: the lidar's noise verdict
        valid &= ~livox_noise(cloud["tag"])
    ring = None
    rings = 0
    no_ring = 0
    if ring_name is not None:
        ids, stray = _ring_ids(cloud[ring_name][valid], ring_name)
        no_ring = int(stray.sum())
        if no_ring:
            ids = ids[~stray]
            valid[np.flatnonzero(valid)[stray]] = False
        ring = ids
        rings = max(int(ring.max()) + 1, 0) if len(ring) else 0
        ring = ring.astype(np.int32)
    keep = last_returns(
        points[valid],
        ring,
        cloud[time_name][valid] if time_name is not None else None,
        cloud[return_name][valid] if return_name is not None else None,
    )
    valid = np.flatnonzero(valid)
    if keep is not None:  # a multi-return cloud: the last return of each beam firing
        valid = valid[keep]
        ring = ring[keep] if ring is not None else None
    raw = cloud[time_name][valid] if time_name is not None else None
    return points[valid], ring, rings, time_name, raw, no_ring


def tagged_noise(msg: Any, msgtype: str) -> int:
    """The points of a Livox message (CustomMsg, or a PointCloud2 with ``tag`` and ``line``
    fields) that :func:`decode_sweep` leaves out as the lidar's high confidence noise."""
    if msgtype in LIVOX_CUSTOM:
        xyz = np.array([(p.x, p.y, p.z) for p in msg.points], dtype=np.float64).reshape(-1, 3)
        tag = np.array([p.tag for p in msg.points], dtype=np.int64)
    elif msgtype == POINT_CLOUD2 and {"tag", "line"} <= {f.name for f in msg.fields}:
        cloud, _ = _cloud_array(msg)
        xyz = np.column_stack([cloud[c].astype(np.float64) for c in "xyz"])
        tag = cloud["tag"]
    else:
        return 0
    returned = np.all(np.isfinite(xyz), axis=1) & np.any(xyz != 0.0, axis=1)
    return int(np.count_nonzero(returned & livox_noise(tag)))


def _decode_cloud(
    msg: Any, time_field: str, time_scales: Mapping[tuple[str, str], float] | None = None
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, int]:
    points, ring, rings, time_name, raw, _ = _cloud_parts(msg, time_field)
    dt = np.zeros(len(points))
    if time_name is not None and raw is not None:
        scale = (time_scales or {}).get(time_key(time_name, raw.dtype))
        dt = _relative_times(raw, stamp_ns(msg.header), scale)
        check_offsets(dt, time_name, raw.dtype, scale)
    return points, ring, dt, rings


def sweep_times(
    msg: Any, time_field: str = "auto"
) -> tuple[
    np.ndarray, int, str | None, np.ndarray | None, int, np.ndarray | None, np.ndarray | None
]:
    """A cloud's points, ring count, time field and raw relative times, for the index.

    Returns ``(points (n, 3), rings, time field or None, values, no ring, ring, absolute)``
    (the points kept, in the sensor's frame): ``values``
    (n,) in the field's own type and unit when the times are offsets (whose unit
    :func:`planodom.datasets.bag_time_units.choose_unit` decides over the topic), None
    without a time field or for absolute times, which are checked here; ``no ring`` the
    points left out for a "no ring" id (:func:`_ring_ids`); ``ring`` (n,) the points' ring
    ids (None without a ring field); ``absolute`` (n,) float64 s after the stamp for
    absolute times (else None).

    Raises:
        ValueError: a malformed cloud, non-finite times, absolute times far off the stamp
            or in a float32 field (which cannot hold a Unix time to the sweep's scale).
    """
    points, ring, rings, time_name, raw, no_ring = _cloud_parts(msg, time_field)
    if time_name is None or raw is None:
        return points, rings, None, None, no_ring, ring, None
    if _is_absolute(raw):
        check_absolute_type(raw, time_name)
        dt = _relative_times(raw, stamp_ns(msg.header))
        check_offsets(dt, time_name, raw.dtype)
        return points, rings, time_name, None, no_ring, ring, dt
    with np.errstate(invalid="ignore"):
        finite = np.isfinite(raw.astype(np.float64))
    if not finite.all():
        check_offsets(np.where(finite, 0.0, np.nan), time_name, raw.dtype)
    if wraps_inside(raw):  # a clock's nanoseconds cut to 32 bits, not the stamps' (time_wraps)
        raise ValueError(f"PointCloud2 {wrap_message(time_name, raw)}")
    return points, rings, time_name, raw, no_ring, ring, None


def check_offsets(
    dt: np.ndarray, time_name: str, dtype: np.dtype, time_scale: float | None = None
) -> None:
    """ValueError naming the field ``time_name`` of type ``dtype`` when a time ``dt`` (s
    from the stamp, read with ``time_scale`` as :func:`decode_sweep`) is NaN or beyond
    :data:`MAX_SWEEP_OFFSET_S`."""
    if np.all(np.abs(dt) <= MAX_SWEEP_OFFSET_S):
        return
    bad = dt[~(np.abs(dt) <= MAX_SWEEP_OFFSET_S)]
    if np.isnan(bad).any():
        raise ValueError(
            f"PointCloud2 time field '{time_name}' ({dtype.name}) is NaN at "
            f"{int(np.isnan(bad).sum())} of {len(dt)} points; --time-field none ignores it"
        )
    worst = bad[np.argmax(np.nan_to_num(np.abs(bad), nan=np.inf))]
    unit = None if time_scale is None else unit_of(time_scale)
    if time_scale is None:
        read = "seconds or nanoseconds (offsets, or since the Unix epoch)"
    else:
        read = f"offsets in {UNIT_WORDS[unit] if unit else f'units of {time_scale:g} s'}"
    raise ValueError(
        f"PointCloud2 time field '{time_name}' ({dtype.name}) puts a point "
        f"{worst:.6g} s from the stamp, beyond {MAX_SWEEP_OFFSET_S:g} s: not {read}; "
        "--time-field none ignores it"
    )


def _time_name(names: tuple[str, ...], time_field: str) -> str | None:
    """The cloud's time field to read (None: no per-point times)."""
    try:
        return time_field_name(names, time_field)
    except ValueError as exc:
        raise ValueError(f"PointCloud2 has {exc}") from None


def _is_absolute(values: np.ndarray) -> bool:
    """True when ``values`` are absolute times by the module docstring's rules."""
    if len(values) == 0:
        return False
    with np.errstate(invalid="ignore"):
        magnitude = np.abs(values.astype(np.float64))
    largest = float(np.max(np.where(np.isfinite(magnitude), magnitude, 0.0)))
    limit = 1e15 if np.issubdtype(values.dtype, np.integer) else 1e8
    return bool(largest > limit)


def _relative_times(values: np.ndarray, stamp: int, scale: float | None = None) -> np.ndarray:
    """Per-point times (see the module docstring) as float64 seconds after ``stamp`` (ns);
    ``scale``: seconds per unit of offsets (None: 1e-9 for integers, 1 for floats)."""
    if np.issubdtype(values.dtype, np.integer):
        ns = values.astype(np.int64)
        if len(ns) and np.abs(ns).max() > 10**15:
            return (ns - stamp).astype(np.float64) * 1e-9
        return ns.astype(np.float64) * (1e-9 if scale is None else scale)
    seconds = values.astype(np.float64)
    if len(seconds) and np.abs(seconds).max() > 1e15:  # absolute nanoseconds as a double
        return (seconds - float(stamp)) * 1e-9
    if len(seconds) and np.abs(seconds).max() > 1e8:
        whole, frac = divmod(stamp, 1_000_000_000)
        return (seconds - whole) - frac * 1e-9
    return seconds if scale is None else seconds * scale


def decode_pose(msg: Any, msgtype: str) -> tuple[int, np.ndarray, str, str]:
    """A reference pose message as ``(stamp ns, T_parent_child (4, 4), parent, child)``.

    ``child`` is ``child_frame_id`` for Odometry and TransformStamped, "" for the pose types
    that have none.

    Raises:
        ValueError: an invalid quaternion or a type that is not in :data:`POSE_TYPES`.
    """
    if msgtype == ODOMETRY:
        pose, child = msg.pose.pose, msg.child_frame_id
    elif msgtype == POSE_STAMPED:
        pose, child = msg.pose, ""
    elif msgtype == POSE_COV_STAMPED:
        pose, child = msg.pose.pose, ""
    elif msgtype == TRANSFORM_STAMPED:
        tr = msg.transform
        T = transform_from_msg(tr.translation, tr.rotation)
        return (
            stamp_ns(msg.header),
            T,
            frame_name(msg.header.frame_id),
            frame_name(msg.child_frame_id),
        )
    else:
        raise ValueError(f"{msgtype} is not a pose message ({', '.join(POSE_TYPES)})")
    T = transform_from_msg(pose.position, pose.orientation)
    return stamp_ns(msg.header), T, frame_name(msg.header.frame_id), frame_name(child)
