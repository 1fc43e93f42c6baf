"""open_recording: one entry point that recognises bags, KITTI sequences and datasets."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bag_factory import SCANNERS, STATIC_TF, T_BASE, write_bag
from kitti_factory import make_sequence

from planodom.datasets import write_dataset
from planodom.datasets.bag_options import BagOptions
from planodom.datasets.kitti import KittiSequence
from planodom.datasets.recording import open_recording, recording_kind
from planodom.datasets.rosbag import BagDataset
from planodom.errors import DatasetError
from planodom.scan import Scan


def test_recognises_each_kind(tmp_path: Path) -> None:
    write_bag(tmp_path / "a.bag", 1, SCANNERS, STATIC_TF, T_BASE)
    write_bag(tmp_path / "b", 2, SCANNERS, STATIC_TF, T_BASE, storage="mcap")
    seq = make_sequence(tmp_path / "kitti", poses_beside=True)
    scans = [Scan(np.zeros((3, 3))), Scan(np.ones((2, 3)))]
    write_dataset(tmp_path / "ds", scans, np.array([0.0, 0.1]))
    (mcap,) = (tmp_path / "b").glob("*.mcap")
    kinds = {p: recording_kind(p) for p in (tmp_path / "a.bag", tmp_path / "b", mcap, seq)}
    assert list(kinds.values()) == ["bag", "bag", "bag", "kitti"]
    assert recording_kind(tmp_path / "ds") == "dataset"
    bag = open_recording(tmp_path / "b", BagOptions(gt_topic="/odom", topics=[]))
    assert isinstance(bag, BagDataset) and len(bag) == 12 and bag.gt_poses is not None
    bag.close()
    assert isinstance(open_recording(seq), KittiSequence)
    assert len(open_recording(tmp_path / "ds")) == 2


def test_bag_options_on_other_recordings(tmp_path: Path) -> None:
    seq = make_sequence(tmp_path, poses_beside=True)
    with pytest.raises(DatasetError, match="gt_topic apply to bags only"):
        open_recording(seq, BagOptions(gt_topic="/odom"))


def test_time_field_reaches_scan_files(tmp_path: Path) -> None:
    # --time-field is a bag option that scan-file recordings honour too
    seq = make_sequence(tmp_path, poses_beside=True)
    with pytest.raises(DatasetError, match=r"\.bin: no time field 'time'"):
        open_recording(seq, BagOptions(time_field="time"))[0]
    plain, ignored = open_recording(seq)[0], open_recording(seq, BagOptions(time_field="none"))[0]
    np.testing.assert_array_equal(plain.points, ignored.points)
