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
        "--skip-bad-scans reads the other parts (their epochs only), as does leaving it out "
        f"of relative_file_paths and files in {rec / 'metadata.yaml'}"
    )
    if storage == "mcap":
        part.write_bytes(data[: len(data) // 2])
        with pytest.raises(DatasetError, match=r"rec_1.mcap, part 2 of the 3 .* is cut short"):
            open_bag(rec)


def _break(part: Path, how: str) -> None:
    data = part.read_bytes()
    if how == "missing":
        part.unlink()
    elif how == "cut":
        part.write_bytes(data[: len(data) // 2])
    else:  # overwritten from its start
        part.write_bytes(bytes(256) + data[256:])


@pytest.mark.parametrize("how", ["missing", "cut", "overwritten"])
def test_a_broken_part_is_named_and_skip_reads_the_others(split, how: str) -> None:
    """Part 2 of 3 missing, cut short or overwritten. Main: a sqlite3 part cut short or
    overwritten, or an mcap part overwritten, was refused without saying which part ("Cannot
    open database ...: database disk image is malformed", "File magic is invalid."), and
    no option read the rest. Now each is named, and ``skip_broken_parts`` reads the other
    parts: the whole bag's epochs outside the part's span, to the bit, the gap noted."""
    whole, rec, storage = split
    ext = ".mcap" if storage == "mcap" else ".db3"
    part = rec / f"rec_1{ext}"
    _break(part, how)
    with pytest.raises(DatasetError, match=rf"{part.name}, part 2 of the 3 .*skip-bad-scans"):
        open_bag(rec)
    options = BagOptions(gt_topic="/odom", skip_broken_parts=True)
    with open_bag(whole, BagOptions(gt_topic="/odom")) as full, open_bag(rec, options) as ds:
        # the part holds the messages recorded from 0.35 s to 0.75 s: epochs 4 to 7
        kept = [k for k, t in enumerate(full.times - full.times[0]) if not 0.35 < t < 0.75]
        assert kept == [0, 1, 2, 3, 8, 9]
        np.testing.assert_array_equal(ds.times, full.times[kept])
        np.testing.assert_array_equal(ds.gt_poses, full.gt_poses[kept])
        for k, scan in zip(kept, ds, strict=True):
            np.testing.assert_array_equal(scan.points, full[k].points)
            np.testing.assert_array_equal(scan.t, full[k].t)
        (note,) = [n for n in ds.notes if part.name in n]
        assert "part 2 of the 3" in note and "left out (--skip-bad-scans)" in note
        t3, t4 = ds.times[3], ds.times[4]
        assert f"a gap between epoch 3 (t = {t3:.3f} s) and epoch 4 (t = {t4:.3f} s)" in note
    assert sorted(p.name for p in rec.iterdir()) == sorted(  # the bag itself untouched
        ["metadata.yaml", f"rec_0{ext}", f"rec_2{ext}"] + ([] if how == "missing" else [part.name])
    )


def test_skipping_the_first_part_or_every_part(split) -> None:
    """The first part left out: the transforms a ROS 2 recorder writes into it are missing,
    and the error says why; every part broken: nothing to read."""
    _, rec, storage = split
    ext = ".mcap" if storage == "mcap" else ".db3"
    options = BagOptions(skip_broken_parts=True)
    (rec / f"rec_0{ext}").unlink()
    with pytest.raises(DatasetError, match=r"no transform .*part 1 of the recording, where"):
        open_bag(rec, options)
    for k in (1, 2):
        (rec / f"rec_{k}{ext}").unlink()
    with pytest.raises(DatasetError, match=r"part 1 of the 3 .* is missing, as are all the others"):
        open_bag(rec, options)
