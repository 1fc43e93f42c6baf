"""Dataset directories: exact round trips, the typed rig.yaml, epoch times, bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from dataset_factory import assert_same_scan, float32_safe, make_scan, random_poses

from planodom.datasets import (
    Dataset,
    load_dataset,
    read_rig,
    write_dataset,
    write_rig,
    write_scan,
    write_tum,
)
from planodom.errors import DatasetError, OutputExistsError
from planodom.rig import Rig
from planodom.scan import Scan

# --------------------------------------------------------------------------- datasets


def test_dataset_round_trip(tmp_path: Path) -> None:
    rng = np.random.default_rng(7)
    scans = [make_scan(rng, n) for n in (30, 0, 12, 1)]
    scans[2] = Scan(scans[2].points, ring=scans[2].ring)  # with and without t, label
    times = np.array([0.0, 0.1, 0.2, 0.35]) + 1234.5
    poses = random_poses(rng, 4)
    extra = {"T_base_scanner": np.eye(4)[:3], "fov_deg": 270.0, "scene": {"seed": np.int64(3)}}
    origins = rng.normal(size=(64, 3))  # one per ring id of make_scan
    rig = Rig(sensor_origins=origins, extrinsics=(np.eye(4),), extra=extra)
    ds = write_dataset(tmp_path / "ds", scans, times, poses, rig)
    assert isinstance(ds, Dataset)

    ds = load_dataset(tmp_path / "ds")
    assert len(ds) == 4
    assert [f.name for f in ds.scan_files] == [f"00000{k}.ply" for k in range(4)]
    for k, scan in enumerate(scans):
        assert_same_scan(ds[k], scan)
    assert_same_scan(ds[-1], scans[-1])
    assert sum(1 for _ in ds) == 4
    with pytest.raises(IndexError):
        ds[4]
    assert np.array_equal(ds.times, times)
    np.testing.assert_allclose(ds.gt_poses, poses, atol=1e-13)
    assert isinstance(ds.rig, Rig) and ds.rig.epoch_rate_hz is None
    assert np.array_equal(ds.rig.sensor_origins, origins)
    assert len(ds.rig.extrinsics) == 1 and np.array_equal(ds.rig.extrinsics[0], np.eye(4))
    assert ds.rig.extra == {
        "T_base_scanner": np.eye(4)[:3].tolist(),
        "fov_deg": 270.0,
        "scene": {"seed": 3},
    }


def test_dataset_pcd_float32(tmp_path: Path) -> None:
    scans = [float32_safe(make_scan(np.random.default_rng(k), 10)) for k in range(3)]
    ds = write_dataset(tmp_path, scans, [0.0, 0.1, 0.2], extension=".pcd", points_dtype=np.float32)
    assert [f.suffix for f in ds.scan_files] == [".pcd"] * 3
    assert np.array_equal(ds[1].points, scans[1].points.astype(np.float32).astype(np.float64))
    assert np.array_equal(ds[1].t, scans[1].t) and ds.gt_poses is None
    assert ds.rig.to_dict() == {}


def test_epoch_times_without_poses(tmp_path: Path) -> None:
    scans = [Scan(np.zeros((1, 3)))] * 5
    ds = write_dataset(tmp_path / "a", scans, np.arange(5) * 0.1)
    np.testing.assert_array_equal(ds.times, np.arange(5) * 0.1)
    ds = write_dataset(tmp_path / "b", scans, np.arange(5) / 20.0, rig=Rig(epoch_rate_hz=20))
    np.testing.assert_array_equal(ds.times, np.arange(5) / 20.0)
    # any increasing times are kept in times.txt (e.g. a bag's clock), exactly
    bag_times = 1.7e9 + np.array([0.0, 0.1003, 0.2001, 0.30007, 0.4])
    ds = write_dataset(tmp_path / "c", scans, bag_times, rig=Rig(epoch_rate_hz=10))
    np.testing.assert_array_equal(ds.times, bag_times)
    # times.txt is read only without poses.tum, and checked line by line
    (tmp_path / "c" / "times.txt").write_text("0\n0.1\nfast\n0.3\n0.4\n")
    with pytest.raises(DatasetError, match=r"times.txt:3: expected one finite time"):
        load_dataset(tmp_path / "c")
    (tmp_path / "c" / "times.txt").write_text("0\n0.1\n0.1\n0.3\n0.4\n")
    with pytest.raises(DatasetError, match=r"times.txt: times must increase \(epoch 2"):
        load_dataset(tmp_path / "c")
    (tmp_path / "c" / "times.txt").write_text("0\n0.1\n")
    with pytest.raises(DatasetError, match=r"times.txt: 2 times for 5 scan files"):
        load_dataset(tmp_path / "c")
    # nanosecond stamps were read as seconds (1.7e18 s apart from any clock)
    (tmp_path / "c" / "times.txt").write_text(
        "".join(f"{1.7e18 + k * 1e8:.0f}\n" for k in range(5))
    )
    with pytest.raises(DatasetError, match=r"times.txt:1: time 1.7e\+18 s is beyond 1e\+11 s"):
        load_dataset(tmp_path / "c")


def test_write_refuses_then_overwrites_without_stale_files(tmp_path: Path) -> None:
    rng = np.random.default_rng(8)
    write_dataset(
        tmp_path,
        [make_scan(rng, 5) for _ in range(5)],
        np.arange(5) * 0.1,
        random_poses(rng, 5),
        rig=Rig(extra={"a": 1}),
    )
    fewer = [make_scan(rng, 5) for _ in range(3)]
    with pytest.raises(OutputExistsError, match="already holds a dataset"):
        write_dataset(tmp_path, fewer, np.arange(3) * 0.1)
    ds = write_dataset(tmp_path, fewer, np.arange(3) * 0.1, overwrite=True)
    assert len(ds) == 3 and ds.gt_poses is None and ds.rig.to_dict() == {}
    assert_same_scan(ds[2], fewer[2])


def test_files_sorted_naturally_and_directory_given_directly(tmp_path: Path) -> None:
    rng = np.random.default_rng(9)
    rows = {}
    for name in ("10", "8", "9", "0000011", "12"):
        rows[name] = rng.normal(size=(4, 4)).astype(np.float32)
        rows[name].tofile(tmp_path / f"{name}.bin")
    (tmp_path / ".hidden").write_text("ignored")
    ds = load_dataset(tmp_path)
    order = ["8", "9", "10", "0000011", "12"]
    assert [f.stem for f in ds.scan_files] == order
    for k, name in enumerate(order):
        assert np.array_equal(ds[k].points, rows[name][:, :3].astype(np.float64))
    np.testing.assert_allclose(ds.times, np.arange(5) * 0.1)

    # poses.tum and rig.yaml beside the scan files are part of the dataset, not scans.
    write_tum(tmp_path / "poses.tum", np.arange(5) + 0.5, random_poses(rng, 5))
    write_rig(tmp_path / "rig.yaml", Rig(epoch_rate_hz=10.0))
    ds = load_dataset(tmp_path)
    assert len(ds) == 5 and ds.rig.to_dict() == {"epoch_rate": 10.0}
    np.testing.assert_array_equal(ds.times, np.arange(5) + 0.5)


def _dataset(tmp_path: Path, n: int = 3) -> Path:
    rng = np.random.default_rng(10)
    write_dataset(
        tmp_path / "ds",
        [make_scan(rng, 4) for _ in range(n)],
        np.arange(n) * 0.1,
        random_poses(rng, n),
        rig=Rig(epoch_rate_hz=10),
    )
    return tmp_path / "ds"


def test_bad_datasets(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match="nowhere does not exist"):
        load_dataset(tmp_path / "nowhere")

    (tmp_path / "empty").mkdir()
    with pytest.raises(DatasetError, match="empty has no scans/ directory"):
        load_dataset(tmp_path / "empty")
    (tmp_path / "empty" / "scans").mkdir()
    with pytest.raises(DatasetError, match=r"scans is empty"):
        load_dataset(tmp_path / "empty")

    root = _dataset(tmp_path)
    (root / "scans" / "notes.txt").write_text("x")
    (root / "scans" / "README").write_text("x")
    with pytest.raises(DatasetError, match="unknown extensions: README, notes.txt"):
        load_dataset(root)
    (root / "scans" / "notes.txt").unlink()
    (root / "scans" / "README").unlink()

    write_scan(root / "scans" / "000003.pcd", make_scan(np.random.default_rng(0), 3))
    with pytest.raises(DatasetError, match="scans: scan files mix extensions .pcd, .ply"):
        load_dataset(root)
    (root / "scans" / "000003.pcd").unlink()

    write_scan(root / "scans" / "000003.ply", make_scan(np.random.default_rng(0), 3))
    with pytest.raises(DatasetError, match="poses.tum: 3 poses for 4 scan files"):
        load_dataset(root)
    (root / "scans" / "000003.ply").unlink()
    load_dataset(root)  # repaired


@pytest.mark.parametrize(
    "text, message",
    [
        ("a: [1, 2\n", "not valid YAML"),
        ("- 1\n- 2\n", "must hold a mapping"),
        ("epoch_rate: -5\n", "field 'epoch_rate' must be positive"),
        ("epoch_rate: fast\n", "field 'epoch_rate' must be a positive number"),
        ("epoch_rate: .inf\n", "field 'epoch_rate' must be positive and finite"),
        ("sensor_origins: [[1, 2]]\n", "field 'sensor_origins' must have shape Nx3"),
        ("motion_bounds: {max_speed: 3}\n", "field 'motion_bounds' has unknown keys"),
    ],
)
def test_bad_rig(tmp_path: Path, text: str, message: str) -> None:
    root = _dataset(tmp_path)
    (root / "rig.yaml").write_text(text)
    with pytest.raises(DatasetError, match=message) as err:
        load_dataset(root)
    assert "rig.yaml" in str(err.value)


def test_a_rig_key_planodom_does_not_read_is_noted(tmp_path: Path) -> None:
    """``epoch_rate_hz: 20`` (a typo of ``epoch_rate``) was kept in ``extra`` without a word,
    the epochs then 0.1 s apart; the keys planodom writes itself are not noted."""
    root = _dataset(tmp_path)
    (root / "rig.yaml").write_text("epoch_rate_hz: 20\nsimulation: {seed: 1}\nsource: rosbag\n")
    ds = load_dataset(root)
    assert ds.rig.epoch_rate_hz is None and ds.rig.extra["epoch_rate_hz"] == 20
    assert [n for n in ds.notes if "rig.yaml" in n] == [
        f"{root / 'rig.yaml'}: 'epoch_rate_hz' not read (planodom reads epoch_rate, "
        "sensor_origins, motion_bounds, extrinsics, platform; a typo?), kept as written"
    ]
    (root / "rig.yaml").write_text("epoch_rate: 20\nsensor_rig: {name: x}\n")
    assert load_dataset(root).notes == []


def test_empty_rig_states_nothing(tmp_path: Path) -> None:
    (tmp_path / "rig.yaml").write_text("")
    rig = read_rig(tmp_path / "rig.yaml")
    assert rig.to_dict() == {} and rig.epoch_rate_hz is None and rig.sensor_origins is None


def test_bad_scan_in_dataset_names_file_when_read(tmp_path: Path) -> None:
    root = _dataset(tmp_path)
    data = (root / "scans" / "000001.ply").read_bytes()
    (root / "scans" / "000001.ply").write_bytes(data[:-3])
    ds = load_dataset(root)  # lazy: the scan is read only when indexed
    ds[0]
    with pytest.raises(DatasetError, match=r"000001\.ply: truncated"):
        ds[1]


def test_malformed_poses_in_dataset(tmp_path: Path) -> None:
    root = _dataset(tmp_path)
    lines = (root / "poses.tum").read_text().splitlines()
    lines[2] = "0.1 0 0 0 0 0 0"
    (root / "poses.tum").write_text("\n".join(lines) + "\n")
    with pytest.raises(DatasetError, match=r"poses\.tum:3: expected 8"):
        load_dataset(root)


def test_point_times_in_another_unit_are_refused(tmp_path: Path) -> None:
    # A 0.1 s sweep written in milliseconds spans 100 "seconds": a thousand epoch periods.
    points = np.random.default_rng(3).normal(size=(50, 3))
    sweep_s = np.linspace(0.0, 0.099, 50)
    good = Scan(points, t=sweep_s)
    bad = Scan(points, t=sweep_s * 1e3)
    ds = write_dataset(tmp_path / "ds", [good, bad, good], [0.0, 0.1, 0.2])
    np.testing.assert_array_equal(ds[0].t, sweep_s)
    with pytest.raises(DatasetError, match=r"000001\.ply: point times \('t'\) span 99 s"):
        ds[1]
    # Several sweeps accumulated into one epoch are within a few periods: read as they are.
    long = Scan(points, t=np.linspace(0.0, 0.5, 50))
    ds = write_dataset(tmp_path / "ds5", [good, long, good], [0.0, 0.1, 0.2])
    np.testing.assert_array_equal(ds[1].t, long.t)


def test_a_results_folder_is_named_as_one(tmp_path: Path) -> None:
    """``run`` / ``smooth`` given a results folder (a run's output, say) answered "files with
    unknown extensions: config.yaml, covariances.npz, ..."; it is named as a results folder,
    with the way to the recording and to ``eval``."""
    names = "poses.tum poses_kitti.txt epochs.csv covariances.npz config.yaml metrics.json"
    names += " timing.json trajectory.png errors.png planes.png"
    for name in names.split():
        (tmp_path / name).write_text("x")
    (tmp_path / "dataset").mkdir()
    with pytest.raises(DatasetError) as exc:
        load_dataset(tmp_path)
    assert str(exc.value) == (
        f"{tmp_path} is a results folder of planodom run or smooth (config.yaml, "
        "covariances.npz), not a recording: give the recording it ran on (its dataset/ is "
        "the one it ran on); `planodom eval` reads its poses.tum"
    )


@pytest.mark.parametrize("kept", ["config.yaml epochs.csv", "epochs.csv metrics.json timing.json"])
def test_a_results_folder_cut_short_is_named_as_one(tmp_path: Path, kept: str) -> None:
    """A results folder without ``covariances.npz`` (cut short, copied in part, or of an
    earlier release) answered "files with unknown extensions: config.yaml, epochs.csv, ..."."""
    for name in ["poses.tum", "trajectory.png", *kept.split()]:
        (tmp_path / name).write_text("x")
    with pytest.raises(DatasetError, match="is a results folder of planodom run or smooth"):
        load_dataset(tmp_path)
