"""ROS 2 split recordings (several storage files, one metadata.yaml): read as the whole
bag; a part missing or cut short is named with what reads the others."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bag_factory import STATIC_TF, T0_NS, T_BASE, Sensor, split_ros2_bag, write_bag

from planodom.datasets.bag_options import BagOptions
from planodom.datasets.rosbag import open_bag
from planodom.errors import DatasetError

CUTS = [T0_NS + 350_000_000, T0_NS + 750_000_000]


def _reading(path: Path) -> list[np.ndarray]:
    with open_bag(path, BagOptions(gt_topic="/odom")) as ds:
        out = [ds.times, ds.gt_poses, ds.rig.sensor_origins]
        for scan in ds:
            out += [scan.points, scan.ring, scan.t]
    return out


@pytest.fixture(params=["sqlite3", "mcap"])
def split(tmp_path: Path, request: pytest.FixtureRequest) -> tuple[Path, Path, str]:
    storage = request.param
    whole = tmp_path / "whole"
    sensors = [Sensor("/points", "lidar", 0, "velodyne")]
    write_bag(whole, 2, sensors, STATIC_TF, T_BASE, storage=storage, duration_s=1.0)
    split_ros2_bag(whole, tmp_path / "rec", CUTS, storage)
    return whole, tmp_path / "rec", storage


def test_a_split_ros2_recording_reads_as_the_whole_bag(split) -> None:
    whole, rec, storage = split
    assert len(list(rec.glob("rec_*"))) == 3
    for a, b in zip(_reading(whole), _reading(rec), strict=True):
        np.testing.assert_array_equal(a, b)
    # one of its storage files given: the recording
    ext = ".mcap" if storage == "mcap" else ".db3"
    with open_bag(rec / f"rec_1{ext}", BagOptions(gt_topic="/odom")) as ds:
        assert len(ds) == 10


def test_a_part_missing_or_cut_short_is_named(split) -> None:
    """A part missing (sqlite3: "Some database files are missing", under "truncated or
    corrupt?") or an mcap part cut short ("File end magic is invalid", no file named)."""
    _, rec, storage = split
    ext = ".mcap" if storage == "mcap" else ".db3"
    part = rec / f"rec_1{ext}"
    data = part.read_bytes()
    part.unlink()
    with pytest.raises(DatasetError) as exc:
        open_bag(rec)
    assert str(exc.value) == (
        f"{rec}: cannot read bag: {part}, part 2 of the 3 metadata.yaml lists, is missing; "
        f"the other parts read once it is left out of relative_file_paths and files in "
        f"{rec / 'metadata.yaml'}"
    )
    if storage == "mcap":
        part.write_bytes(data[: len(data) // 2])
        with pytest.raises(DatasetError, match=r"rec_1.mcap, part 2 of the 3 .* is cut short"):
            open_bag(rec)
