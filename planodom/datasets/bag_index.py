"""Opening a bag and indexing it in one streaming pass: sweeps, tf tree, reference poses.

The index keeps per sweep only its topic, bag time and header stamp (ns), so that memory
stays flat however long the bag; the points are read again epoch by epoch later.
Every reading problem becomes a one-line :class:`~planodom.errors.DatasetError` naming
the bag and, where it applies, the topic or frame.
"""

from __future__ import annotations

import sqlite3
import struct
from array import array
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.interfaces import Connection
from rosbags.rosbag1 import ReaderError as Reader1Error
from rosbags.rosbag2 import ReaderError as Reader2Error
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, TypesysError, get_typestore

from planodom.datasets.bag_beam_notes import BeamCounts
from planodom.datasets.bag_clock import SweepBounds, clock_error, livox_time_error
from planodom.datasets.bag_duplicates import duplicate_sweeps
from planodom.datasets.bag_gt import GtReading, parse_gt
from planodom.datasets.bag_gt_poses import GtPoses
from planodom.datasets.bag_livox import register_livox_types
from planodom.datasets.bag_msgs import (
    LASER_TYPES,
    MAX_SWEEP_OFFSET_S,
    POINT_CLOUD2,
    POINT_FIELD_TYPES,
    SCAN_TYPES,
    check_offsets,
    decode_sweep,
    laser_scan_returns,
    stamp_ns,
    sweep_times,
    tagged_noise,
)
from planodom.datasets.bag_parts import (
    DamagedPartError,
    broken_parts,
    damaged_note,
    damaged_parts,
)
from planodom.datasets.bag_ring_order import RingElevations
from planodom.datasets.bag_rings import ring_counts, stray_span
from planodom.datasets.bag_tf import TF_STATIC_TOPIC, TF_TOPIC, TfTree, frame_name
from planodom.datasets.bag_time_notes import time_like_fields
from planodom.datasets.bag_time_units import TimeUnit, TopicTimes, choose_unit, period_s, time_key
from planodom.datasets.time_wraps import cut_clock_error
from planodom.errors import DatasetError

#: Exceptions of rosbags and the storage libraries that mean a broken or unreadable bag.
BAG_ERRORS: tuple[type[BaseException], ...] = (
    AnyReaderError,
    Reader1Error,
    Reader2Error,
    SerdeError,
    TypesysError,
    struct.error,
    sqlite3.Error,
    EOFError,
    OSError,
    KeyError,
    IndexError,
    AssertionError,
    ValueError,
    OverflowError,
    MemoryError,  # mcap: a corrupt record length
)
try:  # rosbags reads sqlite3 bags through apsw
    import apsw

    BAG_ERRORS = (*BAG_ERRORS, apsw.Error)
except ImportError:  # pragma: no cover
    pass


@contextmanager
def bag_errors(path: Path, what: str = "cannot read bag") -> Iterator[None]:
    """Turn the exceptions of a broken bag into a one-line DatasetError naming ``path``."""
    try:
        yield
    except DatasetError:
        raise
    except BAG_ERRORS as exc:
        damaged = broken_parts(path) if path.is_dir() else []
        if path.is_dir() and not damaged:
            damaged = damaged_parts(path)
        if damaged:
            raise DamagedPartError(f"{path}: {what}: {damaged_note(damaged)}", damaged) from None
        detail = (" ".join(str(exc).split()) or type(exc).__name__)[:200]
        if path.suffix == ".bag" and "index" in detail.lower():  # rosbags reads indexed bags
            detail += "; a ROS 1 recording cut short has no index: `rosbag reindex` rebuilds it"
        raise DatasetError(f"{path}: {what} (truncated or corrupt?): {detail}") from None


def open_reader(path: Path, read_from: Path | None = None) -> AnyReader:
    """An opened AnyReader on the bag at ``path`` (a ``bag_paths.bag_location``), or on
    ``read_from`` standing for it (a ROS 2 bag without its broken parts,
    :func:`.bag_parts.readable_view`; errors name ``path``)."""
    with bag_errors(path):
        typestore = get_typestore(Stores.LATEST)
        register_livox_types(typestore)  # a ROS 2 bag may not carry their definitions
        reader = AnyReader([read_from or path], default_typestore=typestore)
        reader.open()
    return reader


@dataclass
class TopicIndex:
    """What the index pass learnt about one scan topic.

    Attributes:
        name: the topic.
        msgtype: ``sensor_msgs/msg/LaserScan`` or ``sensor_msgs/msg/PointCloud2``.
        frames: the ``header.frame_id`` values of its messages (first seen first).
        rings: 1 for a LaserScan, max ring + 1 for a cloud with a ring field, else 0.
        times: a PointCloud2's relative per-point times (their spans per sweep) by time
            field (``time_key``); time_units: the unit of each
            (:mod:`planodom.datasets.bag_time_units`).
        timed, untimed, unringed: its clouds with points with and without a time field,
            and without a ring field.
        unstamped: messages whose header stamp is 0 (their record time stands for it).
        empty: messages without a point (clouds, Livox messages; 0 for a LaserScan), left
            out of the epochs when some topic has points.
        blank: LaserScans without a return, left out of the epochs when theirs is the only
            scan topic and some of its scans have returns; beams: a 2D scan topic's beam
            counts and intensities (:mod:`planodom.datasets.bag_beam_notes`).
        sweeps: its messages (duplicates included).
        duplicates: messages recorded again (same stamp and content as an earlier one,
            ROS 1's ``header.seq`` aside), left out of the epochs.
        no_ring: points left out for a "no ring" id (its type's largest value).
        noise: points left out as a Livox lidar's high confidence noise (their ``tag``).
        ring_points: points per ring id; ring_span: the ids kept, ``(first, last)``, when
            some are not (:mod:`planodom.datasets.bag_rings`; None: all).
        absolute: per time field read as absolute times, its sweeps' earliest and latest
            time after their stamps, s (:mod:`planodom.datasets.bag_clock`).
        time_like: fields (name -> type) of its clouds without a time field read whose
            names say they may hold times (:mod:`planodom.datasets.bag_time_notes`).
        clock_notes: a few sweeps far from their stamps (:mod:`planodom.datasets.bag_clock`).
        elevations: a cloud's rings' elevations (:mod:`planodom.datasets.bag_ring_order`).
    """

    name: str
    msgtype: str
    frames: list[str] = field(default_factory=list)
    rings: int = 0
    times: dict[tuple[str, str], TopicTimes] = field(default_factory=dict)
    time_units: dict[tuple[str, str], TimeUnit] = field(default_factory=dict)
    timed: int = 0
    untimed: int = 0
    unringed: int = 0
    unstamped: int = 0
    empty: int = 0
    blank: int = 0
    beams: BeamCounts = field(default_factory=BeamCounts)
    duplicates: int = 0
    sweeps: int = 0
    no_ring: int = 0
    noise: int = 0
    ring_points: dict[int, int] = field(default_factory=dict)
    ring_span: tuple[int, int] | None = None
    absolute: dict[str, SweepBounds] = field(default_factory=dict)
    time_like: dict[str, str] = field(default_factory=dict)
    clock_notes: list[str] = field(default_factory=list)
    elevations: RingElevations = field(default_factory=RingElevations)

    @property
    def pointless(self) -> bool:
        """A cloud topic none of whose messages holds a point."""
        return self.msgtype not in LASER_TYPES and self.empty == self.sweeps


@dataclass
class BagIndex:
    """The sweeps (one row each, in the order the bag yields them), tf and reference poses.

    Attributes:
        topics: the scan topics, in ring order.
        sweep_topic: (n,) int32 index into ``topics``.
        sweep_bag_time: (n,) int64 ns, the bag's record time of the message.
        sweep_stamp: (n,) int64 ns, the header stamp (the record time when the stamp is 0).
        sweep_duplicate: (n,) bool, a message recorded again: same topic, stamp and
            content as an earlier one (the first is kept).
        sweep_empty: (n,) bool, a message without a point (a LaserScan: without a return).
        tf: the bag's transform tree.
        gt_times: (M,) int64 ns and ``gt_poses`` (M, 4, 4) ``T_parent_child`` of the
            reference trajectory (empty without ``gt_topic``); ``gt_child`` its child frame.
        gt_read: what reading the reference left out or found repeated.
    """

    topics: list[TopicIndex]
    sweep_topic: np.ndarray
    sweep_bag_time: np.ndarray
    sweep_stamp: np.ndarray
    sweep_duplicate: np.ndarray
    sweep_empty: np.ndarray
    tf: TfTree
    gt_times: np.ndarray
    gt_poses: np.ndarray
    gt_child: str
    gt_read: GtReading = field(default_factory=lambda: GtReading(0))

    def in_epochs(self) -> np.ndarray:
        """(n,) bool, the sweeps that make the epochs: not a duplicate, and not a cloud
        message without any point while some topic has points: it adds nothing to its
        epoch, and its stamp alone would place an epoch without points (bridged by the
        odometry) or move the epochs' windows and reference times; a recording without any
        point keeps them all. A LaserScan without a return is kept in a rig of several scan
        topics: it is normal in a 2D rig, whose other scanners fill the epoch, and its stamp
        keeps the rig's timing; the only scan topic's is left out as a cloud's is."""
        keep = ~self.sweep_duplicate
        if all(t.pointless for t in self.topics):
            return keep
        scan = np.array([t.msgtype in LASER_TYPES for t in self.topics], dtype=bool)
        if len(self.topics) > 1 or self.topics[0].blank == self.topics[0].sweeps:
            return keep & ~(self.sweep_empty & ~scan[self.sweep_topic])
        return keep & ~self.sweep_empty


def select_topics(reader: AnyReader, path: Path, topics: Sequence[str] | None) -> list[str]:
    """The scan topics to read: ``topics`` checked against the bag, or every scan topic."""
    available = reader.topics
    scans = sorted(name for name, info in available.items() if info.msgtype in SCAN_TYPES)
    if topics is None:
        chosen = [name for name in scans if available[name].msgcount > 0]
        if not chosen:
            shown = ", ".join(f"{n} ({available[n].msgtype})" for n in sorted(available))
            raise DatasetError(
                f"{path}: no sensor_msgs/LaserScan, MultiEchoLaserScan or PointCloud2 topic with "
                f"messages (topics: {shown or 'none'}); raw packets or a vendor's point "
                "message must first be decoded to PointCloud2 by the lidar's ROS driver"
            )
        return chosen
    for name in topics:
        if name not in available:
            raise DatasetError(
                f"{path}: no topic '{name}' (scan topics: {', '.join(scans) or 'none'})"
            )
        if available[name].msgtype not in SCAN_TYPES:
            raise DatasetError(
                f"{path}: topic '{name}' is {available[name].msgtype}, not "
                "sensor_msgs/LaserScan, MultiEchoLaserScan or PointCloud2"
            )
        if available[name].msgcount == 0:
            raise DatasetError(f"{path}: topic '{name}' has no messages")
    if len(set(topics)) != len(topics):
        raise DatasetError(f"{path}: topics given more than once: {list(topics)}")
    return list(topics)


def index_bag(
    reader: AnyReader,
    path: Path,
    topics: Sequence[str] | None,
    gt_topic: str | None,
    time_field: str = "auto",
) -> BagIndex:
    """One streaming pass over the scan, tf and reference messages of an opened bag."""
    names = select_topics(reader, path, topics)
    gt = parse_gt(reader, path, gt_topic)
    tree = TfTree(tracked=gt if isinstance(gt, tuple) else None)
    topic_of = {name: i for i, name in enumerate(names)}
    index = [TopicIndex(name, str(reader.topics[name].msgtype)) for name in names]
    wanted = {*names, TF_TOPIC, TF_STATIC_TOPIC} | ({gt} if isinstance(gt, str) else set())
    conns = [c for c in reader.connections if c.topic in wanted]
    rows = array("q")  # topic, bag time, stamp per sweep: 24 bytes each
    empty = array("b")  # per sweep: a message without a point
    seen = [0] * len(names)  # messages per topic so far
    gt_read = GtPoses(gt[1] if isinstance(gt, tuple) else "")
    with bag_errors(path):
        for conn, bag_time, raw in reader.messages(connections=conns):
            msg = _deserialize(reader, path, conn, raw, bag_time)
            if conn.topic in (TF_TOPIC, TF_STATIC_TOPIC):
                with _message_errors(path, conn.topic, bag_time):
                    tree.add(msg, static=conn.topic == TF_STATIC_TOPIC)
            elif conn.topic in topic_of:
                k = topic_of[conn.topic]
                rows.extend((k, bag_time, stamp_ns(msg.header) or bag_time))
                empty.append(_note_sweep(index[k], msg, path, time_field, seen[k]))
                seen[k] += 1
            else:
                gt_read.add(msg, conn.msgtype, bag_time)
    with _message_errors(path, str(gt)):
        gt_read.finish()
    gt_log, gt_invalid = tree.track if isinstance(gt, tuple) else gt_read.log, gt_read.invalid
    if gt is not None and not len(gt_log):
        what = f"/tf transform '{gt[0]}' -> '{gt[1]}'" if isinstance(gt, tuple) else gt
        why = f" (all {len(gt_invalid)} invalid: {gt_invalid[0]})" if gt_invalid else ""
        raise DatasetError(f"{path}: no reference poses in gt {what}{why}")
    table = np.frombuffer(rows, dtype=np.int64).reshape(-1, 3).copy()
    duplicate = duplicate_sweeps(reader, path, topic_of, table)
    for k, topic in enumerate(index):
        rows = table[:, 0] == k
        _choose_time_unit(topic, table[rows, 2], path, np.flatnonzero(duplicate[rows]))
        topic.sweeps = int(rows.sum())
        topic.duplicates = int(duplicate[rows].sum())
        if (span := stray_span(topic.ring_points)) is not None:
            topic.ring_span, topic.rings = span, span[1] + 1
    gt_times, gt_poses = gt_log.arrays()
    reading = GtReading(
        len(gt_times) + len(gt_invalid), gt_invalid[:1], len(gt_invalid), frames=gt_read.frames
    )
    reading.count_repeats(gt_times, gt_poses)
    reading.path_messages, reading.path_recorded = gt_read.path_messages, gt_read.path_recorded
    return BagIndex(
        index,
        table[:, 0].astype(np.int32),
        table[:, 1],
        table[:, 2],
        duplicate,
        np.frombuffer(empty, dtype=np.int8).astype(bool),
        tree,
        gt_times,
        gt_poses,
        gt_read.child,
        reading,
    )


def _deserialize(reader: AnyReader, path: Path, conn: Connection, raw: bytes, bag_time: int) -> Any:
    """A message, or a one-line DatasetError naming the bag, the topic and the message's
    record time ``bag_time`` (ns since the Unix epoch: which of the topic's messages)."""
    try:
        return reader.deserialize(raw, conn.msgtype)
    except BAG_ERRORS as exc:
        detail = " ".join(str(exc).split())[:200]
        raise DatasetError(
            f"{path}: cannot decode a {conn.msgtype} message on topic '{conn.topic}' "
            f"recorded at {_seconds(bag_time)} s (truncated or corrupt?): {detail}"
        ) from None


def _seconds(ns: int) -> str:
    """Integer nanoseconds as exact decimal seconds (``1700000000.502000000``)."""
    sign = "-" if ns < 0 else ""
    return f"{sign}{abs(ns) // 1_000_000_000}.{abs(ns) % 1_000_000_000:09d}"


@contextmanager
def _message_errors(path: Path, topic: str, bag_time: int | None = None) -> Iterator[None]:
    """A ValueError from a decoder as a one-line DatasetError naming the topic (and the
    message's record time ``bag_time``, ns, when given)."""
    try:
        yield
    except ValueError as exc:
        when = "" if bag_time is None else f" (message recorded at {_seconds(bag_time)} s)"
        raise DatasetError(f"{path}: topic '{topic}'{when}: {exc}") from None


def _note_sweep(topic: TopicIndex, msg: Any, path: Path, time_field: str, sweep: int) -> bool:
    """Record a sweep's frame, whether it is stamped and, for a cloud, its largest ring,
    whether it has points and its time offsets (``sweep``: its ordinal in the topic).
    True for a cloud without a point."""
    frame = frame_name(msg.header.frame_id)
    if not frame:
        raise DatasetError(f"{path}: topic '{topic.name}' has a message without frame_id")
    if frame not in topic.frames:
        topic.frames.append(frame)
    stamp = stamp_ns(msg.header)
    topic.unstamped += stamp == 0
    if topic.msgtype in LASER_TYPES:
        topic.rings = 1
        with _message_errors(path, topic.name):
            blank = not laser_scan_returns(msg, topic.msgtype, sweep)
        topic.blank += blank
        topic.beams.add(msg, topic.msgtype)
        return blank
    with _message_errors(path, topic.name):
        if topic.msgtype == POINT_CLOUD2:
            xyz, rings, name, offsets, no_ring, ring, dt = sweep_times(msg, time_field)
            points = len(xyz)
            topic.no_ring += no_ring
            if ring is not None:
                topic.elevations.add(xyz, ring)
            if name is not None and offsets is not None:
                key = time_key(name, offsets.dtype)
                topic.times.setdefault(key, TopicTimes()).add(name, offsets, sweep, stamp)
            if name is not None and dt is not None and len(dt):
                bounds = topic.absolute.setdefault(name, SweepBounds())
                bounds.add(name, _dtype_of(msg, name), float(dt.min()), float(dt.max()), stamp)
            if points:  # a driver relaunched with another layout: noted (bag_notes)
                topic.timed += name is not None
                topic.untimed += name is None
                if name is None and time_field == "auto":
                    fields = [(f.name, _dtype_of(msg, f.name)) for f in msg.fields]
                    topic.time_like.update(time_like_fields(fields))
                topic.unringed += ring is None
        else:
            xyz, ring, dt, rings = decode_sweep(msg, topic.msgtype, time_field)
            points = len(xyz)
            if far := livox_time_error(dt, MAX_SWEEP_OFFSET_S):
                raise ValueError(far)
            if len(dt):  # a Livox CustomMsg: absolute times, on its stamps' clock or not
                bounds = topic.absolute.setdefault("timebase", SweepBounds())
                bounds.add("timebase + offset_time", "", float(dt.min()), float(dt.max()), stamp)
    topic.noise += tagged_noise(msg, topic.msgtype)
    if ring is not None and len(ring):
        for i, n in ring_counts(ring):
            topic.ring_points[i] = topic.ring_points.get(i, 0) + n
    topic.rings = max(topic.rings, rings)
    topic.empty += points == 0
    return points == 0


def _choose_time_unit(
    topic: TopicIndex, stamps: np.ndarray, path: Path, duplicates: np.ndarray
) -> None:
    """Set ``topic.time_units`` from its sweeps' spans and ``stamps`` (ns), per time field,
    each sweep voting once (``duplicates``: the ordinals of its messages recorded again,
    which do not vote); DatasetError when a time then lies too far from its stamp."""
    for key, times in topic.times.items():
        topic.time_units[key] = unit = choose_unit(times.without(duplicates), stamps)
        with _message_errors(path, topic.name):
            plain, cut = (np.frombuffer(a, dtype=np.float64) for a in (times.plain, times.cut))
            if wrapped := cut_clock_error(times.name, times.dtype, plain, cut, period_s(stamps)):
                raise ValueError(wrapped)
            largest = np.array([times.largest * unit.scale])
            check_offsets(largest, times.name, np.dtype(times.dtype), unit.scale)
            far = clock_error(times.bounds, unit.scale, period_s(stamps), "offsets")
            _clock_verdict(topic, far)
    for bounds in topic.absolute.values():
        with _message_errors(path, topic.name):
            _clock_verdict(topic, clock_error(bounds, 1.0, period_s(stamps), "absolute times"))


def _clock_verdict(topic: TopicIndex, verdict: tuple[bool, str] | None) -> None:
    """Raise :func:`clock_error`'s refusal (ValueError), or keep its note in ``topic``."""
    if verdict is not None and verdict[0]:
        raise ValueError(verdict[1])
    if verdict is not None:
        topic.clock_notes.append(f"topic '{topic.name}': {verdict[1]}")


def _dtype_of(msg: Any, name: str) -> str:
    """The numpy name of a PointCloud2's field ``name`` (its first, for the messages)."""
    code = next(int(f.datatype) for f in msg.fields if f.name == name)
    return np.dtype(POINT_FIELD_TYPES[code]).name if code in POINT_FIELD_TYPES else f"type {code}"
