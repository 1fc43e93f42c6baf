"""ROS 1 ``.bag`` files and ROS 2 bag folders (sqlite3 or mcap) as planodom datasets.

Read with the ``rosbags`` package (no ROS install). :func:`open_bag` indexes the bag in one
streaming pass and returns a :class:`BagDataset` (``len(ds)``, ``ds[k] -> Scan``, ``times``,
``gt_poses``, ``rig``) whose scans are read from the bag epoch by epoch;
:func:`convert_bag` writes it as a dataset directory (``scans/*.ply`` with ``ring`` and
``t``, ``poses.tum``, ``rig.yaml``).

- Scan topics: every ``sensor_msgs/LaserScan``, ``MultiEchoLaserScan``
  (:mod:`planodom.datasets.bag_multiecho`) and ``PointCloud2`` topic (and Livox's
  ``CustomMsg``) with messages (sorted by name), or the ``topics`` given (in that order).
- Rings: the topics' rings are numbered in topic order: a (multi-echo) LaserScan topic
  (a 2D scanner) is one ring; a cloud with a ring field takes ``max ring + 1`` rings, its
  ids that are no ring of the lidar's numbering left out
  (:mod:`planodom.datasets.bag_rings`). If a cloud has no ring field the scans carry no
  ``ring``.
- Extrinsics: ``T_base_sensor`` of each message's ``header.frame_id``, chained through
  ``/tf_static`` and the rigid ``/tf`` edges (see :mod:`planodom.datasets.bag_tf`; a loop
  whose chains disagree is noted); a topic none of whose messages goes into the epochs
  needs none.
- Epochs: the sweeps inside each ``1 / epoch_rate`` window (see
  :mod:`planodom.datasets.bag_epochs`), leaving out a message recorded twice (same topic,
  stamp and content: the first is read) and the cloud messages without a point while some
  topic has points (``BagIndex.in_epochs``), and the LaserScans without a return when
  theirs is the only scan topic (in a rig of several, the other scanners fill the epoch:
  kept); ``times`` are the epochs' reference stamps in seconds since the Unix epoch (the
  bag's own clock). A point's ``t`` is its acquisition time minus its epoch's reference time (see
  :mod:`planodom.datasets.bag_msgs` for the per-beam and per-point times). Points are in
  the base frame at their own time: the extrinsics are applied, the vehicle's motion
  within the epoch is not removed.
- Reference: ``gt_topic`` is a ``nav_msgs/Odometry``, ``geometry_msgs/PoseStamped``,
  ``PoseWithCovarianceStamped`` or ``TransformStamped`` topic, or ``"tf:PARENT:CHILD"`` (a
  direct /tf edge). Poses are interpolated at the epoch times (linear + Slerp); when the
  message's child frame is not the base frame but is rigidly linked to it, the result is
  ``T_world_child @ T_child_base``; a child frame not linked, or none named (a
  PoseStamped's), is read as the base frame (noted). Epochs outside the reference's time
  span or in a gap of its poses (:func:`~planodom.datasets.bag_epochs.reference_gaps`) are
  read, their reference poses NaN (noted; the CLI's metrics are over the others and pair
  none across them; :func:`convert_bag` leaves them out); a pose with a NaN or infinite
  value or a zero quaternion is left out (noted).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.highlevel import AnyReader

from planodom.datasets.bag_epochs import NS, group_epochs, interpolate_poses, reference_gaps
from planodom.datasets.bag_gt import childless_note
from planodom.datasets.bag_index import (
    BagIndex,
    bag_errors,
    open_reader,
)
from planodom.datasets.bag_msgs import decode_sweep, stamp_ns
from planodom.datasets.bag_notes import bag_notes, crowded_notes
from planodom.datasets.bag_options import DEFAULT_BASE_FRAME, DEFAULT_EPOCH_RATE, BagOptions
from planodom.datasets.bag_parts import missing_part_note, tf_in_skipped_part
from planodom.datasets.bag_paths import bag_location, split_parts_note
from planodom.datasets.bag_skip import index_skipping
from planodom.datasets.bag_tf import frame_name
from planodom.datasets.bag_topics import BagTopic, bag_rig, bag_topics, has_rings, mount_notes
from planodom.datasets.dataset import write_dataset
from planodom.errors import DatasetError
from planodom.geometry import transform_points
from planodom.scan import Scan

__all__ = [
    "DEFAULT_BASE_FRAME",
    "DEFAULT_EPOCH_RATE",
    "BagConversion",
    "BagDataset",
    "BagOptions",
    "BagTopic",
    "convert_bag",
    "open_bag",
]


class BagDataset:
    """The epochs of a bag, read lazily (see the module docstring).

    Attributes:
        path: the bag (``.bag`` file or ROS 2 folder).
        base_frame: the frame of the points and of ``gt_poses``.
        epoch_rate: epochs per second (Hz) of the windows.
        topics: the scan topics (:class:`BagTopic`), in ring order.
        times: (E,) float64 seconds since the Unix epoch, each epoch's reference time.
        gt_poses: (E, 4, 4) ``T_world_base`` at ``times`` from ``gt_topic``, or None; NaN
            at the epochs outside the reference's time span (it is not extrapolated).
        gt_topic: the reference source as given, or None.
        rig: :class:`~planodom.rig.Rig` with ``epoch_rate_hz``, ``sensor_origins`` per ring
            (the sensors' positions, m, base frame), ``extrinsics`` per topic (its first
            frame) and ``extra`` describing the source (bag, base frame, topics).
        epochs_without_gt: epochs outside the reference's time span or in a gap of its
            poses (NaN in ``gt_poses``; :func:`planodom.datasets.bag_epochs.reference_gaps`).
        notes: one line each on how the bag was read that a user should check (a time
            unit other than the documented one, several point-cloud topics merged); the
            CLI prints them as warnings.

    Use as a context manager (or call :meth:`close`) to release the bag's file handles.
    """

    def __init__(
        self,
        path: Path,
        base_frame: str,
        epoch_rate: float,
        index: BagIndex,
        gt_topic: str | None,
        time_field: str = "auto",
        topics_chosen: bool = False,
        echo: str = "first",
    ) -> None:
        self.path = path
        self.time_field, self.echo = time_field, echo
        self.base_frame = frame_name(base_frame)
        self.epoch_rate = float(epoch_rate)
        self.gt_topic = gt_topic
        self._index = index
        self.topics = bag_topics(path, self.base_frame, index)
        far_mounts = mount_notes(path, self.base_frame, self.topics)
        used = np.flatnonzero(index.in_epochs())
        grouped, ref = group_epochs(index.sweep_stamp[used], round(NS / self.epoch_rate))
        members = [used[m] for m in grouped]
        self.gt_poses: np.ndarray | None = None
        self.epochs_without_gt = 0
        self._gt_gap: tuple[int, int] | None = None
        if gt_topic is not None:
            inside, poses = interpolate_poses(index.gt_times, index.gt_poses, ref)
            if not inside.any():
                raise DatasetError(
                    f"{path}: gt '{gt_topic}' spans no epoch time (reference poses from "
                    f"{index.gt_times.min() / NS:.3f} to {index.gt_times.max() / NS:.3f} s, "
                    f"epochs from {ref.min() / NS:.3f} to {ref.max() / NS:.3f} s: the "
                    "scans' header stamps on another clock, such as the sensor's own?)"
                )
            self.gt_poses = np.full((len(ref), 4, 4), np.nan)
            self.gt_poses[inside] = poses @ self._child_to_base(index.gt_child)
            in_gap, self._gt_gap = reference_gaps(index.gt_times, ref, round(NS / self.epoch_rate))
            self.gt_poses[in_gap] = np.nan
            self.epochs_without_gt = int((~inside | in_gap).sum())
        self._members = members
        self._ref = ref
        self.times = ref.astype(np.float64) / NS
        self.rig = bag_rig(path, self.base_frame, self.epoch_rate, gt_topic, self.topics)
        self.notes = split_parts_note(path) + index.tf.loops(self.base_frame) + far_mounts
        self.notes += index.tf.restated_notes() + index.tf.ignored_notes()
        self.notes += bag_notes(index, topics_chosen, gt_topic, echo) + crowded_notes(
            index, members, self.times
        )
        if gt_topic is not None and not index.gt_child:  # a PoseStamped: of which frame?
            sensors = {f: T for t in self.topics for f, T in t.T_base_sensor.items()}
            self.notes.append(
                childless_note(index.gt_read, gt_topic, self.base_frame, sensors, index.tf.moving)
            )
        elif gt_topic is not None and index.tf.lookup(index.gt_child, self.base_frame) is None:
            self.notes.append(
                f"gt '{gt_topic}': its poses are of frame '{index.gt_child}', which no static "
                f"transform links to the base frame '{self.base_frame}': read as the base "
                "frame's poses, off by the lever arm between the two (give "
                f"'{index.gt_child}' as --base-frame, or record the transform in /tf_static)"
            )
        if self.epochs_without_gt:
            self.notes.append(
                self.partial_gt_note(
                    "every epoch is read; the metrics are over the epochs it spans"
                )
            )
        self._reader: AnyReader | None = None
        #: the folder read instead of ``path`` (its readable parts), and what holds it
        self.read_from: Path | None = None
        self._view: object = None

    def partial_gt_note(self, what: str) -> str:
        """The note on a reference that spans only some of the epochs, ending in ``what``."""
        gt = self._index.gt_times
        spanned = len(self) - self.epochs_without_gt
        gap = ""
        if self._gt_gap is not None:
            a, b = self._gt_gap
            gap = f" with a gap from {a / NS:.3f} to {b / NS:.3f} s"
        return (
            f"gt '{self.gt_topic}' spans {spanned} of the {len(self)} epochs (reference poses "
            f"from {gt.min() / NS:.3f} to {gt.max() / NS:.3f} s{gap}, epochs from "
            f"{self.times[0]:.3f} to {self.times[-1]:.3f} s): {what}"
        )

    def _child_to_base(self, child: str) -> np.ndarray:
        """``T_child_base`` when the reference's child frame is rigidly linked, else identity
        (noted)."""
        if not child or child == self.base_frame:
            return np.eye(4)
        T = self._index.tf.lookup(child, self.base_frame)
        return np.eye(4) if T is None else T

    def __len__(self) -> int:
        return len(self._members)

    def __repr__(self) -> str:
        gt = "with" if self.gt_poses is not None else "without"
        return f"BagDataset({str(self.path)!r}, {len(self)} epochs, {gt} ground truth)"

    def _open(self) -> AnyReader:
        if self._reader is None:
            self._reader = open_reader(self.path, self.read_from)
        return self._reader

    def close(self) -> None:
        """Close the bag (it is reopened if the dataset is indexed again)."""
        if self._reader is not None:
            reader, self._reader = self._reader, None
            reader.close()

    def __enter__(self) -> BagDataset:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __getitem__(self, index: int) -> Scan:
        """Epoch ``index``'s scan, read from the bag (negative indices count from the end)."""
        n = len(self)
        if not -n <= index < n:
            raise IndexError(f"epoch {index} out of range for {n} epochs")
        sweeps = self._members[index % n]
        idx = self._index
        wanted = Counter(
            (int(idx.sweep_topic[s]), int(idx.sweep_bag_time[s]), int(idx.sweep_stamp[s]))
            for s in sweeps
        )
        start = int(idx.sweep_bag_time[sweeps].min())
        stop = int(idx.sweep_bag_time[sweeps].max()) + 1
        found = []
        for k, bag_time, msg in self._scan_messages(start, stop):
            key = (k, bag_time, stamp_ns(msg.header) or bag_time)
            if wanted[key] > 0:
                wanted[key] -= 1
                found.append((k, key[2], msg))
        if sum(wanted.values()):
            raise DatasetError(f"{self.path}: epoch {index}: sweeps indexed but not read back")
        return self._scan(found, int(self._ref[index % n]))

    def __iter__(self) -> Iterator[Scan]:
        """The epochs in order, in a single pass over the bag (flat memory)."""
        idx = self._index
        epoch_of = np.full(len(idx.sweep_stamp), -1, dtype=np.int64)
        for e, sweeps in enumerate(self._members):
            epoch_of[sweeps] = e
        pending: dict[int, list[tuple[int, int, Any]]] = {}
        next_epoch = 0
        for s, (k, bag_time, msg) in enumerate(self._scan_messages(None, None)):
            e = int(epoch_of[s])
            if e < 0:
                continue
            pending.setdefault(e, []).append((k, stamp_ns(msg.header) or bag_time, msg))
            while next_epoch < len(self) and len(pending.get(next_epoch, ())) == len(
                self._members[next_epoch]
            ):
                yield self._scan(pending.pop(next_epoch), int(self._ref[next_epoch]))
                next_epoch += 1
        if next_epoch != len(self):
            raise DatasetError(f"{self.path}: epoch {next_epoch}: sweeps indexed but not read")

    def _scan_messages(self, start: int | None, stop: int | None) -> Iterator[tuple[int, int, Any]]:
        """``(topic index, bag time, message)`` of the scan topics in ``[start, stop)`` ns."""
        reader = self._open()
        topic_of = {t.name: k for k, t in enumerate(self.topics)}
        conns = [c for c in reader.connections if c.topic in topic_of]
        with bag_errors(self.path):
            for conn, bag_time, raw in reader.messages(connections=conns, start=start, stop=stop):
                yield topic_of[conn.topic], bag_time, reader.deserialize(raw, conn.msgtype)

    def _scan(self, sweeps: list[tuple[int, int, Any]], ref: int) -> Scan:
        """The scan of one epoch from its ``(topic index, stamp ns, message)`` sweeps."""
        points, rings, times = [], [], []
        for k, stamp, msg in sorted(sweeps, key=lambda s: (s[0], s[1])):
            topic = self.topics[k]
            try:
                pts, ring, dt, _ = decode_sweep(
                    msg, topic.msgtype, self.time_field, topic.time_scales, self.echo
                )
            except ValueError as exc:
                raise DatasetError(f"{self.path}: topic '{topic.name}': {exc}") from None
            if ring is not None and topic.ring_span is not None:  # ids that are no ring
                keep = (ring >= topic.ring_span[0]) & (ring <= topic.ring_span[1])
                pts, ring, dt = pts[keep], ring[keep], dt[keep]
            if ring is not None and topic.renumber is not None:  # ids in elevation order
                ring = topic.renumber[1][np.searchsorted(topic.renumber[0], ring)]
            if ring is not None:
                order = np.argsort(ring, kind="stable")
                pts, ring, dt = pts[order], ring[order], dt[order]
                rings.append(ring + topic.first_ring)
            T = topic.T_base_sensor[frame_name(msg.header.frame_id)]
            points.append(transform_points(T, pts))
            times.append((stamp - ref) / NS + dt)
        ringed = has_rings(self.topics)
        return Scan(
            np.concatenate(points) if points else np.zeros((0, 3)),
            np.concatenate(rings).astype(np.int32) if ringed and rings else None,
            np.concatenate(times) if times else np.zeros(0),
        )


def open_bag(path: str | Path, options: BagOptions | None = None) -> BagDataset:
    """Index a ROS 1 ``.bag`` or ROS 2 bag folder and return it as a lazy dataset.

    Args:
        path: a ``.bag`` file, a ROS 2 bag folder (with ``metadata.yaml``) or its ``.db3`` /
            ``.mcap`` file.
        options: base frame, epoch rate, scan topics and reference (:class:`BagOptions`;
            None: the defaults, ``base_link`` at 10 Hz, every scan topic, no reference).

    Raises:
        DatasetError: one line naming the bag and the topic or frame: missing or corrupt
            bag, no scan topic, an unknown or non-scan topic, a scanner frame without a
            transform to the base frame, an unusable ``gt_topic``.
    """
    opts = options or BagOptions()
    location = bag_location(path)
    index, broken, view = index_skipping(location, opts)
    read_from = None if view is None else Path(view.name)
    if len(index.sweep_stamp) == 0:
        raise DatasetError(f"{location}: no messages on the scan topics")
    with tf_in_skipped_part(broken):
        ds = BagDataset(
            location,
            opts.base_frame,
            opts.epoch_rate,
            index,
            opts.gt_topic,
            opts.time_field,
            topics_chosen=bool(opts.topics),
            echo=opts.echo,
        )
    ds.read_from, ds._view = read_from, view
    ds.notes[:0] = [missing_part_note(part, ds.times) for part in broken]
    return ds


@dataclass(frozen=True)
class BagConversion:
    """What :func:`convert_bag` wrote.

    Attributes:
        bag: the bag read; out_dir: the dataset written.
        epochs: epochs written; points: points written in all.
        topics: the scan topics, in ring order; rings: total ring count (0: no rings).
        start_time, end_time: first and last epoch time, seconds since the Unix epoch.
        gt_topic: the reference source, or None; dropped_epochs: epochs outside its span.
        notes: :attr:`BagDataset.notes`.
    """

    bag: Path
    out_dir: Path
    epochs: int
    points: int
    topics: tuple[str, ...]
    rings: int
    start_time: float
    end_time: float
    gt_topic: str | None
    dropped_epochs: int
    notes: tuple[str, ...] = ()


def convert_bag(
    bag_path: str | Path,
    out_dir: str | Path,
    options: BagOptions | None = None,
    *,
    overwrite: bool = False,
) -> BagConversion:
    """Convert a bag into a dataset directory (``options`` as :func:`open_bag`).

    Writes ``scans/NNNNNN.ply`` (float64 ``x y z``, ``ring``, ``t``), ``rig.yaml`` and the
    bag's epoch times (seconds since the Unix epoch): with a ``gt_topic`` in ``poses.tum``
    beside the reference poses, else in ``times.txt``. Scans are streamed: memory stays
    flat. The epochs outside the reference's time span are left out (``poses.tum`` holds
    a reference pose for each scan) and noted.

    Raises:
        DatasetError: see :func:`open_bag`; ``out_dir`` already holds a dataset and not
            ``overwrite``.
        OutputError: ``out_dir`` is, lies in or contains the bag (a ROS 2 bag's folder).
    """
    with open_bag(bag_path, options) as ds:
        spanned = np.ones(len(ds), dtype=bool)
        notes = list(ds.notes)
        if ds.gt_poses is not None and ds.epochs_without_gt:
            spanned = np.isfinite(ds.gt_poses[:, 0, 0])
            left = (
                "the epoch" if ds.epochs_without_gt == 1 else f"the {ds.epochs_without_gt} epochs"
            )
            notes[-1] = ds.partial_gt_note(
                f"{left} outside it left out (without --gt-topic every epoch is written)"
            )
        counter = _CountingScans(ds, spanned)
        inputs = (bag_path, ds.path)  # a ROS 2 bag's .db3 / .mcap stands for its folder
        gt = None if ds.gt_poses is None else ds.gt_poses[spanned]
        times = ds.times[spanned]
        write_dataset(out_dir, counter, times, gt, ds.rig, overwrite=overwrite, inputs=inputs)
        return BagConversion(
            ds.path,
            Path(out_dir),
            len(counter),
            counter.points,
            tuple(t.name for t in ds.topics),
            sum(t.rings for t in ds.topics) if has_rings(ds.topics) else 0,
            float(times[0]),
            float(times[-1]),
            ds.gt_topic,
            ds.epochs_without_gt,
            tuple(notes),
        )


class _CountingScans:
    """The ``spanned`` (E,) bool epochs of a dataset as a streamed sequence for
    ``write_dataset``, counting the points."""

    def __init__(self, ds: BagDataset, spanned: np.ndarray) -> None:
        self.ds = ds
        self.epochs = np.flatnonzero(spanned)
        self.spanned = spanned
        self.points = 0

    def __len__(self) -> int:
        return len(self.epochs)

    def __getitem__(self, index: int) -> Scan:
        return self.ds[int(self.epochs[index])]

    def __iter__(self) -> Iterator[Scan]:
        for scan, keep in zip(self.ds, self.spanned, strict=True):
            if keep:
                self.points += len(scan)
                yield scan
