"""Bags as other recorders and drivers leave them: a ROS 2 storage file without its
``metadata.yaml`` (an mcap file as Foxglove records it, a bag's file copied alone) or
compressed whole (``.mcap.zstd``), a LaserScan whose beams cannot be placed, a static
transform given again with another value. Each read as its bag, refused in one line naming
the message or the way out, or noted."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import numpy as np
import pytest
from bag_factory import (
    SCANNERS,
    STATIC_TF,
    T0_NS,
    T_BASE,
    BagWriter,
    Truth,
    laser_scan,
    pose,
    true_pose,
    write_bag,
)
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

from planodom.datasets.recording import recording_kind
from planodom.datasets.rosbag import open_bag
from planodom.errors import DatasetError
from tests.datasets.test_bag_paths import _reading


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_a_storage_file_alone_reads_as_its_bag(tmp_path: Path, storage: str) -> None:
    """Refused before as an unfinished recording (`ros2 bag reindex`, which needs ROS),
    although rosbags reads such a file alone; now the same reading as the bag folder's."""
    bag = tmp_path / "bag"
    write_bag(bag, 2, SCANNERS[:2], STATIC_TF, T_BASE, storage=storage, duration_s=0.6)
    (part,) = (p for p in bag.iterdir() if p.suffix in (".db3", ".mcap"))
    alone = tmp_path / "alone" / f"drive{part.suffix}"
    alone.parent.mkdir()
    shutil.copy(part, alone)
    assert recording_kind(alone) == "bag"
    for a, b in zip(_reading(bag), _reading(alone), strict=True):
        np.testing.assert_array_equal(a, b)
    with open_bag(alone) as ds:
        assert ds.path == alone and ds.notes == []
    # another storage file beside it: a split recording's part, read alone, noted
    shutil.copy(part, alone.parent / f"drive_1{part.suffix}")
    with open_bag(alone) as ds:
        assert len(ds.notes) == 1 and ds.notes[0].startswith(f"drive_1{part.suffix} beside ")
        assert "ros2 bag reindex" in ds.notes[0]


def test_a_storage_file_cut_short_or_its_folder_names_the_way_out(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    write_bag(bag, 2, SCANNERS[:1], STATIC_TF, T_BASE, storage="mcap", duration_s=0.3)
    (bag / "metadata.yaml").unlink()
    (part,) = bag.glob("*.mcap")
    with pytest.raises(DatasetError) as exc:  # the folder: its one complete file named
        open_bag(bag)
    assert "ros2 bag reindex" in str(exc.value) and f"give {part.name} itself" in str(exc.value)
    part.write_bytes(part.read_bytes()[:-100])  # not closed: no mcap end magic
    for given in (bag, part):
        with pytest.raises(DatasetError) as exc:
            open_bag(given)
        assert "no metadata.yaml" in str(exc.value) and "itself" not in str(exc.value)


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_a_storage_file_compressed_whole_reads_as_its_bag(tmp_path: Path, storage: str) -> None:
    """Its ``.db3.zstd`` / ``.mcap.zstd`` given: "dataset ... is not a directory" before."""
    _scan_bag(tmp_path / "z", {}, storage=storage, zstd=True)
    (part,) = (tmp_path / "z").glob("*.zstd")
    assert recording_kind(part) == "bag"
    with open_bag(part) as ds, open_bag(tmp_path / "z") as folder:
        assert ds.path == folder.path == tmp_path / "z" and len(ds) == 6
    alone = tmp_path / part.name
    shutil.copy(part, alone)
    with pytest.raises(DatasetError) as exc:
        open_bag(alone)
    assert str(exc.value) == (
        f"{alone} is a ROS 2 storage file compressed whole (zstd) without its bag's "
        f"metadata.yaml: `zstd -d` it and give the {part.suffixes[-2]} file"
    )


def _scan_bag(
    path: Path, change: dict[str, float], at: int = 3, storage: str = "sqlite3", zstd: bool = False
) -> None:
    """Six LaserScans of /scan_front, sweep ``at`` with the fields ``change``; ``zstd``: the
    storage file compressed whole (``ros2 bag record --compression-mode file``)."""
    truth = Truth(T_base_sensor=T_BASE)
    writer = BagWriter(path, 2, storage)
    if zstd:
        writer.writer.set_compression(CompressionMode.FILE, CompressionFormat.ZSTD)
    with writer as bw:
        bw.write("/tf_static", bw.tf([bw.transform_stamped(T0_NS, *e) for e in STATIC_TF]), T0_NS)
        for k in range(6):
            stamp = T0_NS + k * 100_000_000
            msg = laser_scan(bw, truth, "/scan_front", "laser_front", stamp)
            if k == at:
                msg = dataclasses.replace(msg, **change)
            bw.write("/scan_front", msg, stamp + 2_000_000)


@pytest.mark.parametrize(
    ("change", "said"),
    [
        ({"angle_increment": float("nan")}, "angle_increment nan"),
        ({"angle_min": float("inf")}, "angle_min inf"),
        ({"time_increment": float("nan")}, "time_increment nan"),
        ({"range_min": float("nan")}, "range_min nan"),
        ({"angle_increment": 0.0}, "angle_increment 0 under several beams"),
    ],
)
def test_a_laser_scan_whose_beams_cannot_be_placed_is_refused(
    tmp_path: Path, change: dict[str, float], said: str
) -> None:
    """Read before as NaN points (angles), infinite point times (times) or a scan without a
    return (range_min), without a word; or all on one ray (an angle increment of 0)."""
    _scan_bag(tmp_path / "b", change)
    with pytest.raises(DatasetError) as exc:
        open_bag(tmp_path / "b")
    message = str(exc.value)
    assert "\n" not in message and "topic '/scan_front'" in message
    assert f"LaserScan stamped 1700000000.300 s has {said}" in message


def test_a_laser_scan_turning_the_other_way_or_without_returns_is_read(tmp_path: Path) -> None:
    """A negative angle increment (a scanner turning clockwise) and, in a scan without a
    return, a NaN angle increment are no error."""
    _scan_bag(tmp_path / "neg", {"angle_increment": -0.01, "angle_min": 2.0})
    _scan_bag(
        tmp_path / "empty",
        {"angle_increment": float("nan"), "ranges": np.full(400, np.inf, np.float32)},
    )
    with open_bag(tmp_path / "neg") as ds:
        scan = list(ds)[3]
        angles = np.arctan2(scan.points[:, 1], scan.points[:, 0])
        assert np.all(np.diff(np.unwrap(angles)) < 0)  # listed clockwise
    with open_bag(tmp_path / "empty") as ds:
        assert len(ds) == 5


def _tf_bag(path: Path, ros: int, restated: np.ndarray | None) -> None:
    """Sweeps of /scan_front, /odom; /tf_static given again before the fourth sweep with
    ``mount -> laser_front`` set to ``restated`` (None: the same values, as a latched topic
    recorded twice)."""
    truth = Truth(T_base_sensor=T_BASE)
    with BagWriter(path, ros) as bw:
        bw.write("/tf_static", bw.tf([bw.transform_stamped(T0_NS, *e) for e in STATIC_TF]), T0_NS)
        for k in range(6):
            stamp = T0_NS + k * 100_000_000
            bw.write("/odom", bw.odometry(stamp, true_pose(stamp / 1e9)), stamp)
            if k == 3:
                edges = [
                    (p, c, restated if c == "laser_front" and restated is not None else T)
                    for p, c, T in STATIC_TF
                ]
                tf = [bw.transform_stamped(stamp, *e) for e in edges]
                bw.write("/tf_static", bw.tf(tf), stamp + 1_000_000)
            msg = laser_scan(bw, truth, "/scan_front", "laser_front", stamp)
            bw.write("/scan_front", msg, stamp + 2_000_000)


@pytest.mark.parametrize("ros", [1, 2])
def test_a_static_transform_given_another_value_is_noted(tmp_path: Path, ros: int) -> None:
    """The last value was used for the whole bag without a word; now noted, with the
    change measured from the first value (5 cm, 3 deg here)."""
    (_, _, T_first) = next(e for e in STATIC_TF if e[1] == "laser_front")
    moved = T_first @ pose(0.0, 0.0, np.radians(3.0), (0.03, 0.04, 0.0))
    suffix = ".bag" if ros == 1 else ""
    _tf_bag(tmp_path / f"same{suffix}", ros, None)
    _tf_bag(tmp_path / f"moved{suffix}", ros, moved)
    with open_bag(tmp_path / f"same{suffix}") as same, open_bag(tmp_path / f"moved{suffix}") as ds:
        assert same.notes == []
        assert ds.notes == [
            "/tf_static: 'mount' -> 'laser_front' is given another value 1 time(s), up to "
            "0.050 m and 3.00 deg from its first (two static publishers of one frame, or an "
            "extrinsic set again mid-bag?); the last is used for the whole bag"
        ]
        # the last value is the one used
        T_mount = next(T for p, c, T in STATIC_TF if c == "mount")
        np.testing.assert_allclose(ds.rig.extrinsics[0], T_mount @ moved, atol=1e-9)
