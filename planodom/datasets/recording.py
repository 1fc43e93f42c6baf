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

from pathlib import Path
from typing import Any, Literal

from planodom.datasets.bag_options import BagOptions
from planodom.datasets.bag_paths import is_bag, is_bag_part, unfinished_bag
from planodom.datasets.bin_scan import check_bin_layout
from planodom.datasets.dataset import load_dataset
from planodom.datasets.kitti import is_kitti_sequence, load_kitti_sequence
from planodom.datasets.rosbag import open_bag
from planodom.errors import DatasetError

RecordingKind = Literal["bag", "kitti", "dataset"]


def recording_kind(path: str | Path) -> RecordingKind:
    """What :func:`open_recording` will read at ``path``: "bag", "kitti" or "dataset"."""
    path = Path(path)
    if is_bag(path) or is_bag_part(path):
        return "bag"
    if is_kitti_sequence(path):
        return "kitti"
    return "dataset"


def open_recording(
    path: str | Path, options: BagOptions | None = None, bin_layout: str = "auto"
) -> Any:
    """Open a bag, a KITTI sequence or a dataset directory as a dataset.

    Args:
        path: the recording (see the module docstring).
        options: bags: base frame, epoch rate (Hz), scan topics and reference
            (:class:`~planodom.datasets.bag_options.BagOptions`; None: the defaults); its
            ``time_field`` applies to scan files too (``none``: their point times ignored).
        bin_layout: ``.bin`` scan files only: ``auto`` (from each file's size and columns;
            a KITTI sequence is read in KITTI's layout), ``kitti`` or ``nuscenes``
            (:mod:`planodom.datasets.bin_scan`).

    Raises:
        DatasetError: one line naming the file, topic or frame; also when a bag option
            other than its default is given for a recording that is not a bag.
    """
    kind = recording_kind(path)
    check_bin_layout(bin_layout)
    if kind == "bag":
        if bin_layout != "auto":
            raise DatasetError(f"{path} is a bag: --bin-layout applies to .bin scan files only")
        return open_bag(path, options)
    unfinished = unfinished_bag(path)
    if unfinished:
        raise DatasetError(unfinished)
    given = options.given() if options is not None else []
    given = [g for g in given if g not in ("time_field", "skip_broken_parts")]
    time_field = options.time_field if options is not None else "auto"
    if given:
        raise DatasetError(f"{path} is not a bag: options {', '.join(given)} apply to bags only")
    if kind == "kitti":
        layout = "kitti" if bin_layout == "auto" else bin_layout
        return load_kitti_sequence(path, layout, time_field)
    return load_dataset(path, bin_layout, time_field)
