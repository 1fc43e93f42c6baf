"""ROS 2 split recordings (several storage files, one metadata.yaml): read as the whole
bag; a part missing or cut short is named with what reads the others."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bag_factory import STATIC_TF, T0_NS, T_BASE, Sensor, split_ros2_bag, write_bag

from planodom.datasets.bag_options import BagOptions
from planodom.datasets.recording import open_recording
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
    # its metadata.yaml given (before: "dataset .../metadata.yaml is not a directory")
    with open_recording(rec / "metadata.yaml") as ds:
        assert len(ds) == 10
    for a, b in zip(_reading(rec / "metadata.yaml"), _reading(rec), strict=True):
        np.testing.assert_array_equal(a, b)


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
    elif how == "overwritten":  # from its start
        part.write_bytes(bytes(256) + data[256:])
    else:  # damaged further in: it opens, reading its messages fails
        part.write_bytes(_damaged(bytearray(data), part.suffix == ".mcap"))


def _damaged(data: bytearray, mcap: bool) -> bytes:
    """A storage file damaged further in, its magics and schema intact: in an mcap file
    the length of the middle record of its first chunk overwritten with 0xff bytes; in a
    sqlite3 file the link of an overflow page (a cloud's blob continues there) to the next
    one zeroed."""
    if mcap:  # records: opcode (1 byte), length (8, little-endian), content
        at = 8  # after the magic
        while data[at] != 0x06:  # the first chunk
            at += 9 + int.from_bytes(data[at + 1 : at + 9], "little")
        name = int.from_bytes(data[at + 37 : at + 41], "little")  # its compression's
        start = at + 41 + name + 8  # its records
        end = start + int.from_bytes(data[start - 8 : start], "little")
        heads = []
        while start < end:
            heads.append(start)
            start += 9 + int.from_bytes(data[start + 1 : start + 9], "little")
        middle = heads[len(heads) // 2]
        data[middle + 1 : middle + 9] = b"\xff" * 8
        return bytes(data)
    n = len(data)
    pages = n // 4096
    for a in range(pages // 2 * 4096, n, 4096):  # not a b-tree page (types 2, 5, 10, 13)
        if data[a] not in (2, 5, 10, 13) and 1 < int.from_bytes(data[a : a + 4], "big") <= pages:
            data[a : a + 4] = bytes(4)
            return bytes(data)
    raise AssertionError("no overflow page")  # pragma: no cover


@pytest.mark.parametrize("how", ["missing", "cut", "overwritten", "damaged"])
def test_a_broken_part_is_named_and_skip_reads_the_others(split, how: str) -> None:
    """Part 2 of 3 missing, cut short, overwritten or damaged further in. Main: a sqlite3
    part cut short or overwritten, or an mcap part overwritten, was refused without saying
    which part ("Cannot open database ...: database disk image is malformed", "File magic
    is invalid."), and no option read the rest; a part that opens but is damaged further in
    still was ("database disk image is malformed", "Python int too large to convert to C
    ssize_t"). Now each is named, and ``skip_broken_parts`` reads the other
    parts: the whole bag's epochs outside the part's span, to the bit, the gap noted."""
    whole, rec, storage = split
    ext = ".mcap" if storage == "mcap" else ".db3"
    part = rec / f"rec_1{ext}"
    _break(part, how)
    with pytest.raises(DatasetError, match=rf"{part.name}, part 2 of the 3 .*skip-bad-scans"):
        open_bag(rec)
    if how == "damaged":
        with pytest.raises(DatasetError, match=r"opens but cannot be read to its end \("):
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


def test_a_part_missing_and_another_damaged_further_in_are_both_left_out(split) -> None:
    """Part 2 missing and part 3 damaged further in: the first is left out before reading,
    the second once reading it failed; epochs 0 to 3 read, both noted."""
    whole, rec, storage = split
    ext = ".mcap" if storage == "mcap" else ".db3"
    _break(rec / f"rec_1{ext}", "missing")
    _break(rec / f"rec_2{ext}", "damaged")
    with open_bag(whole) as full, open_bag(rec, BagOptions(skip_broken_parts=True)) as ds:
        np.testing.assert_array_equal(ds.times, full.times[:4])
        for k, scan in enumerate(ds):
            np.testing.assert_array_equal(scan.points, full[k].points)
        notes = [n for n in ds.notes if "left out (--skip-bad-scans)" in n]
        assert len(notes) == 2
        assert "part 2 of the 3" in notes[0] and "is missing" in notes[0]
        assert "part 3 of the 3" in notes[1] and "opens but cannot be read" in notes[1]
        assert "the run ends at epoch 3" in notes[1]
