"""KITTI odometry sequences: layout, frame conversion against hand-computed poses, writer,
and the devkit's segment errors against hand-computed values."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from evo.tools import file_interface
from kitti_factory import POINTS, TR, P, make_sequence

from planodom.datasets.kitti import (
    is_kitti_sequence,
    load_kitti_sequence,
    read_kitti_poses,
    write_kitti_camera_poses,
)
from planodom.errors import DatasetError
from planodom.metrics_kitti import kitti_segment_errors


@pytest.mark.parametrize("poses_beside", [False, True])
def test_sequence_layout_and_velodyne_frame_truth(tmp_path: Path, poses_beside: bool) -> None:
    seq = make_sequence(tmp_path, poses_beside)
    assert is_kitti_sequence(seq) and not is_kitti_sequence(seq / "velodyne")
    ds = load_kitti_sequence(seq)
    assert len(ds) == 3
    assert np.allclose(ds.times, [0.0, 0.1037359, 0.207472])
    for k, pts in enumerate(POINTS):
        assert np.array_equal(ds[k].points, pts[:, :3].astype(np.float64))
    assert np.allclose(ds.Tr, TR)
    # by hand: 1 m forward along the camera's z is 1 m along the Velodyne's x
    expected_1 = np.eye(4)
    expected_1[0, 3] = 1.0
    # by hand: the camera turned right by 90 deg 2 m ahead; the Velodyne, 0.27 m behind the
    # camera, yawed -90 deg about its z and sits at x = 2 + 0.27, y = +0.27
    expected_2 = np.array(
        [[0.0, 1.0, 0.0, 2.27], [-1.0, 0.0, 0.0, 0.27], [0.0, 0.0, 1.0, 0.0], [0, 0, 0, 1]]
    )
    assert np.allclose(ds.gt_poses[0], np.eye(4), atol=1e-9)
    assert np.allclose(ds.gt_poses[1], expected_1, atol=1e-9)
    assert np.allclose(ds.gt_poses[2], expected_2, atol=1e-9)
    assert ds.rig.epoch_rate_hz == 10.0 and np.array_equal(ds.rig.sensor_origins, np.zeros((1, 3)))


def test_camera_pose_writer_round_trips(tmp_path: Path) -> None:
    seq = make_sequence(tmp_path, poses_beside=True)
    ds = load_kitti_sequence(seq)
    out = tmp_path / "07.txt"
    write_kitti_camera_poses(out, ds.gt_poses, ds.Tr)
    # read back by evo (the reader evo_ape kitti uses): the camera poses of the file
    traj = file_interface.read_kitti_poses_file(str(out))
    assert np.allclose(np.array(traj.poses_se3), P, atol=1e-9)
    assert np.allclose(read_kitti_poses(out), P, atol=1e-9)


def test_sequence_errors(tmp_path: Path) -> None:
    seq = make_sequence(tmp_path, poses_beside=True)
    (seq / "times.txt").write_text("0\n0.1\n")
    with pytest.raises(DatasetError, match="times.txt: 2 times for 3 scans"):
        load_kitti_sequence(seq)
    (seq / "times.txt").unlink()
    (seq / "calib.txt").write_text("P0: 1 2 3\n")
    with pytest.raises(DatasetError, match=r"calib.txt: no 'Tr:' line"):
        load_kitti_sequence(seq)
    (seq / "calib.txt").write_text("Tr: 1 2 3\n")
    with pytest.raises(DatasetError, match=r"calib.txt:1: 'Tr' must hold 12"):
        load_kitti_sequence(seq)


# ------------------------------------------------------------------ segment errors


def straight(n: int, step: float = 1.0) -> np.ndarray:
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, 0, 3] = step * np.arange(n)
    return poses


def test_segment_errors_scale_drift_by_hand() -> None:
    # 151 frames 1 m apart: 100 m segments start at frames 0, 10, ..., 40 and end at the first
    # frame more than 100 m on (first + 101); the estimate is 1 % too long, so each segment's
    # error is 1.01 m over L = 100 m: 1.01 %, and no rotation error.
    gt = straight(151)
    est = straight(151, 1.01)
    result = kitti_segment_errors(est, gt)
    assert result["segments"] == 5
    assert result["translation_pct"] == pytest.approx(1.01)
    assert result["rotation_deg_per_100m"] == pytest.approx(0.0, abs=1e-9)
    assert list(result["per_length"]) == [100]
    assert result["length_m"] == pytest.approx(150.0)


def test_segment_errors_yaw_drift_by_hand() -> None:
    # the estimate yaws 1e-4 rad more per frame: over a 101-frame segment the rotation error
    # is 101e-4 rad over 100 m = 0.5787 deg / 100 m
    gt = straight(151)
    est = gt.copy()
    for k in range(151):
        c, s = math.cos(1e-4 * k), math.sin(1e-4 * k)
        est[k, :2, :2] = [[c, -s], [s, c]]
    result = kitti_segment_errors(est, gt)
    assert result["rotation_deg_per_100m"] == pytest.approx(math.degrees(101e-4), rel=1e-6)


def test_segment_errors_short_sequence_is_nan() -> None:
    result = kitti_segment_errors(straight(50), straight(50))
    assert math.isnan(result["translation_pct"]) and math.isnan(result["rotation_deg_per_100m"])
    assert result["segments"] == 0 and result["per_length"] == {}


def test_segment_errors_in_the_camera_frame() -> None:
    # Velodyne poses driving 1 m per frame along x are camera poses driving along z; with a
    # 1 % scale error the devkit's numbers are the same in both frames for a pure translation
    gt, est = straight(151), straight(151, 1.01)
    result = kitti_segment_errors(est, gt, Tr=TR)
    assert result["translation_pct"] == pytest.approx(1.01)
    assert result["length_m"] == pytest.approx(150.0)
