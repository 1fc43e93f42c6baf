"""One entry point for every recording the CLI accepts: :func:`open_recording`.

Recognised, in this order:

- a ROS 1 ``.bag`` file, or a ROS 2 bag folder (``metadata.yaml``) or its ``.db3`` /
  ``.mcap`` file -> :class:`~planodom.datasets.rosbag.BagDataset`;
- a KITTI odometry sequence folder (``velodyne/`` and ``calib.txt``) ->
  :class:`~planodom.datasets.kitti.KittiSequence`;
- anything else -> :func:`~planodom.datasets.dataset.load_dataset` (a dataset directory or
  a directory of scan files).

Every dataset returned has ``len(ds)``, ``ds[k] -> Scan``, ``times`` (E,), ``gt_poses``
(E, 4, 4) or None, and ``rig``.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

from planodom.datasets.bag_index import is_bag
from planodom.datasets.dataset import load_dataset
from planodom.datasets.kitti import is_kitti_sequence, load_kitti_sequence
from planodom.datasets.rosbag import DEFAULT_BASE_FRAME, DEFAULT_EPOCH_RATE, open_bag
from planodom.errors import DatasetError

RecordingKind = Literal["bag", "kitti", "dataset"]


def recording_kind(path: str | Path) -> RecordingKind:
    """What :func:`open_recording` will read at ``path``: "bag", "kitti" or "dataset"."""
    path = Path(path)
    if is_bag(path) or (path.suffix in (".db3", ".mcap") and is_bag(path.parent)):
        return "bag"
    if is_kitti_sequence(path):
        return "kitti"
    return "dataset"


def open_recording(
    path: str | Path,
    *,
    base_frame: str = DEFAULT_BASE_FRAME,
    epoch_rate: float = DEFAULT_EPOCH_RATE,
    topics: Sequence[str] | None = None,
    gt_topic: str | None = None,
) -> Any:
    """Open a bag, a KITTI sequence or a dataset directory as a dataset.

    Args:
        path: the recording (see the module docstring).
        base_frame: bags only: tf frame the points are expressed in (``--base-frame``).
        epoch_rate: bags only: epochs per second, Hz (``--epoch-rate``).
        topics: bags only: scan topics in ring order (repeated ``--topic``; None: all).
        gt_topic: bags only: reference pose topic or ``"tf:PARENT:CHILD"`` (``--gt-topic``).

    Raises:
        DatasetError: one line naming the file, topic or frame; also when a bag option is
            given for a recording that is not a bag.
    """
    topics = list(topics) if topics else None  # a CLI's empty repeated option: all topics
    kind = recording_kind(path)
    if kind == "bag":
        return open_bag(
            path, base_frame=base_frame, epoch_rate=epoch_rate, topics=topics, gt_topic=gt_topic
        )
    given = [
        name
        for name, value, default in (
            ("base_frame", base_frame, DEFAULT_BASE_FRAME),
            ("epoch_rate", epoch_rate, DEFAULT_EPOCH_RATE),
            ("topics", topics, None),
            ("gt_topic", gt_topic, None),
        )
        if value != default
    ]
    if given:
        raise DatasetError(f"{path} is not a bag: options {', '.join(given)} apply to bags only")
    if kind == "kitti":
        return load_kitti_sequence(path)
    return load_dataset(path)
