"""Scan files named by their clouds' stamps (as pcl_ros saves a bag's clouds): the epoch
times are those stamps, a dropped cloud included; names read two ways are not read."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from planodom.datasets import load_dataset
from planodom.datasets.pcd import write_pcd

SEC = 1_700_000_000
#: Stamps (ns after SEC) of 6 clouds at 10 Hz, the fourth (0.3 s) dropped.
OFFSETS_NS = [0, 100_000_000, 200_000_000, 400_000_000, 500_000_000, 605_000_000]
NAMES = {
    "ros1": lambda ns: f"{SEC + ns // 10**9}.{ns % 10**9:09d}.pcd",  # bag_to_pcd: SEC.NSEC
    "ros2": lambda ns: f"{SEC + ns // 10**9}_{ns % 10**9}.pcd",  # ROS 2: SEC_NSEC, unpadded
    "ns": lambda ns: f"cloud_{SEC * 10**9 + ns}.pcd",  # integer nanoseconds after a prefix
    "decimal": lambda ns: f"{(SEC * 10**9 + ns) / 1e9:.6f}.pcd",  # seconds, 6 decimals
}


def _directory(folder: Path, name_of, absolute: bool = False) -> list[int]:
    """Write one 4-point PCD per stamp; its ``timestamp`` field (Hesai / RoboSense: float64
    absolute seconds) 10.3 ms after the stamp and on, or ``time`` offsets (float32 s)."""
    folder.mkdir()
    for ns in OFFSETS_NS:
        xyz = np.array([[5.0, 0, 0], [0, 5.0, 0], [-5.0, 0, 0], [0, -5.0, 0]], np.float32)
        fields = {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]}
        offsets = 0.0103 + 0.02 * np.arange(4)  # off the 10 ms grid, as real times are
        if absolute:
            fields["timestamp"] = SEC + ns / 1e9 + offsets
        else:
            fields["time"] = offsets.astype(np.float32)
        write_pcd(folder / name_of(ns), fields)
    return OFFSETS_NS


@pytest.mark.parametrize("style", list(NAMES))
def test_stamps_in_the_file_names_are_the_epoch_times(tmp_path: Path, style: str) -> None:
    """They were taken 0.1 s apart from 0, the dropped cloud's gap lost, the Unix clock too."""
    offsets = _directory(tmp_path / "clouds", NAMES[style])
    ds = load_dataset(tmp_path / "clouds")
    expected = (SEC * 10**9 + np.array(offsets)) / 1e9
    np.testing.assert_allclose(ds.times, expected, rtol=0, atol=1e-6 if style == "decimal" else 0)
    assert len(ds.notes) == 1 and "epoch times from the scan file names" in ds.notes[0]
    assert "0.100 s median, 0.200 s largest" in ds.notes[0]


def test_absolute_point_times_are_made_relative_to_the_stamp_in_the_name(tmp_path: Path) -> None:
    """Absolute point times (float64 Unix s) were made relative to each scan's first point
    (the epochs on no Unix clock): 0 for the first point, which lies 10.3 ms after the stamp."""
    _directory(tmp_path / "clouds", NAMES["ros1"], absolute=True)
    ds = load_dataset(tmp_path / "clouds")
    for k in range(len(ds)):
        np.testing.assert_allclose(ds[k].t, 0.0103 + 0.02 * np.arange(4), atol=1e-6)


def test_names_read_two_ways_or_with_two_prefixes_are_not_read(tmp_path: Path) -> None:
    """``SEC.FRACTION`` with fractions of several lengths: decimals or unpadded ns? Not read
    (noted); the epochs stay 0.1 s apart. Two prefixes, or stamps out of the Unix range or
    not increasing, are no stamps (no note)."""
    _directory(tmp_path / "a", lambda ns: f"{SEC + ns // 10**9}.{ns % 10**9}.pcd")
    ds = load_dataset(tmp_path / "a")
    np.testing.assert_allclose(ds.times, np.arange(6) * 0.1)
    assert len(ds.notes) == 1 and "fractions have different lengths" in ds.notes[0]
    _directory(tmp_path / "b", lambda ns: f"{'a' if ns < 3e8 else 'b'}_{SEC * 10**9 + ns}.pcd")
    ds = load_dataset(tmp_path / "b")
    np.testing.assert_allclose(ds.times, np.arange(6) * 0.1)
    assert ds.notes == []
    _directory(tmp_path / "c", lambda ns: f"{ns // 10**6:09d}_{ns % 10**6}.pcd")  # not Unix
    assert load_dataset(tmp_path / "c").notes == []


def test_a_reference_at_its_own_rate_in_poses_tum_says_what_to_do(tmp_path: Path) -> None:
    """A 100 Hz reference put beside 6 clouds as poses.tum: refused, and the error said
    only the counts; it says now that `planodom eval` compares such a reference."""
    from planodom.datasets import write_tum
    from planodom.errors import DatasetError

    _directory(tmp_path / "clouds", NAMES["ros1"])
    times = SEC + np.arange(70) * 0.01
    write_tum(tmp_path / "clouds" / "poses.tum", times, np.tile(np.eye(4), (70, 1, 1)))
    with pytest.raises(DatasetError, match=r"70 poses for 6 scan files .* `planodom eval`"):
        load_dataset(tmp_path / "clouds")


def _kitti_raw(folder: Path, lines: list[str]) -> Path:
    """KITTI raw's ``velodyne_points``: ``data/0000000000.bin``, ... and ``timestamps.txt``."""
    (folder / "data").mkdir(parents=True)
    for k in range(len(lines)):
        rows = np.array([[5.0, 0, 0, 0.1], [0, 5.0, 0, 0.2], [-5.0, 0, 0, 0.3]], np.float32)
        rows.tofile(folder / "data" / f"{k:010d}.bin")
    (folder / "timestamps.txt").write_text("".join(f"{line}\n" for line in lines))
    for name in ("timestamps_start.txt", "timestamps_end.txt"):
        (folder / name).write_text("".join(f"{line}\n" for line in lines))
    return folder


def test_kitti_raw_timestamps_are_the_epoch_times(tmp_path: Path) -> None:
    """KITTI raw's ``velodyne_points/data`` was read 0.1 s apart from 0, its
    ``timestamps.txt`` (the scans' times, a dropped scan's gap included) unread; the folder
    itself was refused for the unknown timestamps files without saying where the scans are."""
    lines = [
        "2011-09-26 13:02:25.964389445",
        "2011-09-26 13:02:26.068572790",
        "2011-09-26 13:02:26.275000000",  # a scan dropped before it
        "2011-09-26 13:02:26.379",
    ]
    raw = _kitti_raw(tmp_path / "velodyne_points", lines)
    ds = load_dataset(raw / "data")
    base = 1317042145  # 2011-09-26 13:02:25 UTC
    expected_ns = np.array([964389445, 1068572790, 1275000000, 1379000000])
    np.testing.assert_allclose(ds.times - base, expected_ns / 1e9, atol=1e-6)
    assert ds.notes == [
        f"{raw / 'data'}: epoch times from KITTI raw's {raw / 'timestamps.txt'} (read as UTC, "
        "steps 0.104 s median, 0.206 s largest)"
    ]
    from planodom.errors import DatasetError

    with pytest.raises(DatasetError, match=r"a KITTI raw folder: give its scans, .*data$"):
        load_dataset(raw)
    (raw / "timestamps.txt").write_text("\n".join(lines[:3]) + "\n")
    with pytest.raises(DatasetError, match=r"timestamps.txt: 3 times for 4 scan files"):
        load_dataset(raw / "data")
    (raw / "timestamps.txt").write_text("\n".join([*lines[:3], "13:02:26.379"]) + "\n")
    with pytest.raises(DatasetError, match=r"timestamps.txt:4: expected a time"):
        load_dataset(raw / "data")


def test_a_kitti_raw_folder_is_a_car_unless_its_rig_yaml_says_otherwise(tmp_path: Path) -> None:
    lines = ["2011-09-26 13:02:25.964389445", "2011-09-26 13:02:26.068572790"]
    raw = _kitti_raw(tmp_path / "velodyne_points", lines)
    assert load_dataset(raw / "data").rig.platform == "vehicle"
    (raw / "data" / "rig.yaml").write_text("platform: handheld\n")
    assert load_dataset(raw / "data").rig.platform == "handheld"
    (raw / "timestamps.txt").unlink()  # a folder of scans: nothing declared
    (raw / "data" / "rig.yaml").unlink()
    assert load_dataset(raw / "data").rig.platform is None
