"""KITTI odometry sequences: layout, frame conversion against hand-computed poses, writer,
and the devkit's segment errors against hand-computed values."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from evo.tools import file_interface
from kitti_factory import POINTS, TR, P, make_sequence

from planodom.config import PlanodomConfig
from planodom.datasets.kitti import (
    is_kitti_sequence,
    load_kitti_sequence,
    read_kitti_poses,
    write_kitti_camera_poses,
)
from planodom.datasets.recording import open_recording
from planodom.errors import DatasetError
from planodom.metrics_kitti import kitti_segment_errors
from planodom.odometry import with_platform


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


def test_a_sequence_is_a_car_and_the_config_may_say_otherwise(tmp_path: Path) -> None:
    ds = load_kitti_sequence(make_sequence(tmp_path, True))
    assert ds.rig.platform == "vehicle"
    assert with_platform(PlanodomConfig(), ds.rig).odometry.start_vehicle_twist
    handheld = PlanodomConfig().updated({"odometry.platform": "handheld"})
    resolved = with_platform(handheld, ds.rig).odometry
    assert (resolved.platform, resolved.start_vehicle_twist) == ("handheld", False)


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
    with pytest.raises(DatasetError, match="times.txt: 2 times for 3 scan files"):
        load_kitti_sequence(seq)
    (seq / "times.txt").unlink()
    (seq / "calib.txt").write_text("P0: 1 2 3\n")
    with pytest.raises(DatasetError, match=r"calib.txt: no 'Tr:' line .*; its keys: P0$"):
        load_kitti_sequence(seq)
    # KITTI object / tracking's calib (another key): its keys named
    (seq / "calib.txt").write_text("P0: 1 2 3\nTr_velo_to_cam: 1 0 0 0 0 1 0 0 0 0 1 0\n")
    with pytest.raises(DatasetError, match=r"its keys: P0, Tr_velo_to_cam$"):
        load_kitti_sequence(seq)
    (seq / "calib.txt").write_text("Tr: 1 2 3\n")
    with pytest.raises(DatasetError, match=r"calib.txt:1: 'Tr' must hold 12"):
        load_kitti_sequence(seq)


@pytest.mark.parametrize(
    ("text", "line"),
    [
        ("0\nnan\n0.2\n", 2),  # NaN compared false in the increase check: read as a time
        ("0\n0.1\ninf\n", 3),
        ("0 1\n0.1 1\n0.2 1\n", 1),  # two columns were read as (E, 2) times
    ],
)
def test_times_that_are_not_one_finite_number_a_line_are_refused(
    tmp_path: Path, text: str, line: int
) -> None:
    seq = make_sequence(tmp_path, poses_beside=True)
    (seq / "times.txt").write_text(text)
    with pytest.raises(DatasetError, match=rf"times.txt:{line}: expected one finite time"):
        load_kitti_sequence(seq)


def test_times_with_comments_and_blank_lines_are_read(tmp_path: Path) -> None:
    seq = make_sequence(tmp_path, poses_beside=True)
    (seq / "times.txt").write_text("# seconds\n0\n\n0.1\n0.25\n")
    assert np.array_equal(load_kitti_sequence(seq).times, [0.0, 0.1, 0.25])


def test_without_times_a_gap_in_the_numbering_is_refused_and_the_rate_noted(
    tmp_path: Path,
) -> None:
    """Without times.txt the scans are 0.1 s apart: a missing scan was silently one step."""
    seq = make_sequence(tmp_path, poses_beside=False)
    (seq / "times.txt").unlink()
    ds = load_kitti_sequence(seq)
    assert np.allclose(ds.times, [0.0, 0.1, 0.2])
    assert len(ds.notes) == 1 and "no times.txt" in ds.notes[0]
    (seq / "velodyne" / "000002.bin").rename(seq / "velodyne" / "000003.bin")
    (tmp_path / "dataset" / "poses" / "07.txt").unlink()
    with pytest.raises(DatasetError, match=r"000003.bin: follows 000001.bin .* no times.txt"):
        load_kitti_sequence(seq)
    assert (
        make_sequence(tmp_path / "b", poses_beside=True)
        and not load_kitti_sequence(tmp_path / "b" / "dataset" / "sequences" / "07").notes
    )


KITTI_IDENTITY = "1 0 0 0 0 1 0 0 0 0 1 0"


def test_sequence_without_calib_says_so(tmp_path: Path) -> None:
    """It said '<seq> has no scans/ directory and no scan files' (read as a dataset)."""
    seq = make_sequence(tmp_path, poses_beside=True)
    (seq / "calib.txt").unlink()
    with pytest.raises(DatasetError, match=r"07 has velodyne/ but no calib.txt: a KITTI"):
        open_recording(seq)


@pytest.mark.parametrize(
    ("rotation", "problem"),
    [
        ("0 0 0 0 0 0 0 0 0", "column norms 0, 0, 0, not 1"),  # was a LinAlgError traceback
        ("2 0 0 0 1 0 0 0 1", "column norms 2, 1, 1, not 1"),  # was used as a pose
        ("-1 0 0 0 1 0 0 0 1", "a reflection"),
        ("1 0.6 0 0 0.8 0 0 0 1", "not orthogonal"),
    ],
)
def test_calib_tr_that_is_no_rigid_transform_is_refused(
    tmp_path: Path, rotation: str, problem: str
) -> None:
    seq = make_sequence(tmp_path, poses_beside=True)
    r = rotation.split()
    tr = " ".join(r[0:3] + ["0.1"] + r[3:6] + ["0.2"] + r[6:9] + ["0.3"])
    (seq / "calib.txt").write_text(f"P0: {KITTI_IDENTITY}\nTr: {tr}\n")
    with pytest.raises(
        DatasetError, match=rf"calib.txt:2: 'Tr' is not a rigid transform .*{problem}"
    ):
        load_kitti_sequence(seq)


def test_pose_file_line_that_is_no_rigid_pose_is_refused(tmp_path: Path) -> None:
    """A scaled rotation block (a typo, a projection matrix) was read as a pose: every
    metric against it silently wrong. KITTI's own 6-digit rotations stay accepted."""
    path = tmp_path / "poses.txt"
    six_digits = (  # a rotation in KITTI's %e with 7 significant digits: R^T R off by ~1e-6
        "9.999978e-01 5.272628e-04 -2.066935e-03 -4.690294e-02 -5.296506e-04 "
        "9.999992e-01 -1.154865e-03 -2.839928e-02 2.066324e-03 1.155958e-03 9.999971e-01 "
        "8.586941e-01"
    )
    path.write_text(f"{KITTI_IDENTITY}\n{six_digits}\n\n1.5 0 0 0 0 1 0 0 0 0 1 0\n")
    with pytest.raises(DatasetError, match=r"poses.txt:4: not a rigid pose .*1.5, 1, 1.*1 such"):
        read_kitti_poses(path)
    path.write_text(f"{KITTI_IDENTITY}\n{six_digits}\n")
    assert read_kitti_poses(path)[1, 2, 3] == 8.586941e-01


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
