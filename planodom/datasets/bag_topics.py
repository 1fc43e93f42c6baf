"""The scan topics of a bag as read (:class:`BagTopic`: rings, extrinsics, sweeps) and the
typed :class:`~planodom.rig.Rig` they make (:func:`bag_rig`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from planodom.datasets.bag_index import BagIndex
from planodom.datasets.bag_ring_order import ring_renumbering
from planodom.mounts import check_mounts
from planodom.rig import Rig


@dataclass(frozen=True, eq=False)
class BagTopic:
    """A scan topic as read.

    Attributes:
        name: the topic.
        msgtype: ``sensor_msgs/msg/LaserScan`` or ``sensor_msgs/msg/PointCloud2``.
        first_ring: ring id of the topic's ring 0 in the scans.
        rings: number of rings (1 for a LaserScan; 0: a cloud without ring field).
        T_base_sensor: (frame -> (4, 4)) extrinsics of the frames its messages name (none
            for a topic :attr:`left_out`).
        sweeps: number of messages.
        time_scales: seconds per unit of a cloud's per-point time offsets by time field
            (``time_key``, :mod:`planodom.datasets.bag_time_units`); a field without one:
            the documented reading.
        empty: no message holds a point (its lack of rings costs the others none; a
            cloud message without a point places no epoch when some topic has points).
        read: its messages that go into the epochs (``BagIndex.in_epochs``: not recorded
            twice, not a cloud without a point while some topic has points).
        frame: the first frame its messages name.
        ring_span: the ring ids read, ``(first, last)``, when some ids are not rings
            (:mod:`planodom.datasets.bag_rings`); None: every id.
        renumber: ``(ids, new ids)`` when its ring ids do not follow its beams' elevations
            (:mod:`planodom.datasets.bag_ring_order`); None: read as they are.
    """

    name: str
    msgtype: str
    first_ring: int
    rings: int
    T_base_sensor: dict[str, np.ndarray]
    sweeps: int
    time_scales: dict[tuple[str, str], float] = field(default_factory=dict)
    empty: bool = False
    read: int = 0
    frame: str = ""
    ring_span: tuple[int, int] | None = None
    renumber: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def left_out(self) -> bool:
        """None of its messages goes into the epochs: it needs no extrinsic and gives none."""
        return self.read == 0 and self.sweeps > 0

    @property
    def ringless(self) -> bool:
        """Its points carry no ring (a topic without any point has none to carry)."""
        return self.rings == 0 and not self.empty


def has_rings(topics: list[BagTopic]) -> bool:
    """Whether the scans carry rings: some topic has rings and every other one too, or no
    point at all (a topic that never held a point takes no rings away)."""
    return any(t.rings > 0 for t in topics) and not any(t.ringless for t in topics)


def bag_topics(path: Path, base_frame: str, index: BagIndex) -> list[BagTopic]:
    """The topics with their ring numbering and extrinsics: every frame of a topic that
    goes into the epochs must resolve; a topic none of whose messages does (a cloud topic
    without any point beside one with points) needs no transform and gets none."""
    read = np.bincount(index.sweep_topic[index.in_epochs()], minlength=len(index.topics)).tolist()
    topics, first = [], 0
    for t, n in zip(index.topics, read, strict=True):
        where = f"{path}: topic '{t.name}'"
        extr = {f: index.tf.require(base_frame, f, where) for f in t.frames} if n else {}
        scales = {key: unit.scale for key, unit in t.time_units.items()}
        topics.append(
            BagTopic(
                t.name,
                t.msgtype,
                first,
                t.rings,
                extr,
                t.sweeps,
                scales,
                t.pointless,
                n,
                t.frames[0],
                t.ring_span,
                ring_renumbering(t.elevations, t.ring_span),
            )
        )
        first += t.rings
    return topics


def mount_notes(path: Path, base_frame: str, topics: list[BagTopic]) -> list[str]:
    """Notes of sensor frames far from the base frame (:func:`planodom.mounts.check_mounts`);
    DatasetError naming the transform for one beyond any vehicle (millimetres, or a base
    frame not on the vehicle)."""
    hint = (
        f", or the base frame '{base_frame}' not on the vehicle (--base-frame: the "
        "vehicle's own frame, such as base_link)"
    )
    mounts = [
        (f"{path}: topic '{t.name}': transform '{base_frame}' -> '{frame}'", T[:3, 3])
        for t in topics
        for frame, T in t.T_base_sensor.items()
    ]
    return check_mounts(mounts, hint)


def bag_rig(
    path: Path, base_frame: str, epoch_rate: float, gt_topic: str | None, topics: list[BagTopic]
) -> Rig:
    """The typed rig of a bag: rate, per-ring sensor origins, extrinsics of the topics read
    (a topic left out of the epochs gives none), source. ``extra``'s per-topic ``sweeps``
    counts the messages read into the epochs, ``left_out`` (when any) the others."""
    used = [t for t in topics if not t.left_out]
    first_T = [next(iter(t.T_base_sensor.values())) for t in used]
    origins = None
    if has_rings(topics):
        origins = np.concatenate(
            [np.tile(T[:3, 3], (t.rings, 1)) for t, T in zip(used, first_T, strict=True)]
        )
    elif len(topics) == 1:
        origins = first_T[0][:3, 3][None]
    extra = {
        "source": "rosbag",
        "bag": str(path),
        "base_frame": base_frame,
        "gt_topic": gt_topic,
        "topics": [_topic_extra(t) for t in topics],
    }
    return Rig(epoch_rate, origins, None, tuple(first_T), extra)


def _topic_extra(t: BagTopic) -> dict[str, Any]:
    """A topic's entry in ``rig.extra['topics']``."""
    out: dict[str, Any] = {
        "topic": t.name,
        "type": t.msgtype.split("/")[-1],
        "frame": t.frame,
        "first_ring": t.first_ring,
        "rings": t.rings,
        "sweeps": t.read,
    }
    if t.read != t.sweeps:
        out["left_out"] = t.sweeps - t.read
    return out
