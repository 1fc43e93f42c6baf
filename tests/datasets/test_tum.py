"""TUM trajectories: exact round trips, evo compatibility, bad lines named."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from dataset_factory import random_poses
from evo.core.trajectory import PoseTrajectory3D
from evo.tools import file_interface
from scipy.spatial.transform import Rotation

from planodom.datasets import read_tum, write_tum
from planodom.errors import DatasetError

# --------------------------------------------------------------------------- poses


def test_tum_round_trip_exact_and_evo_compatible(tmp_path: Path) -> None:
    rng = np.random.default_rng(6)
    times = np.cumsum(rng.uniform(0.05, 0.15, 40)) + 1.6e9
    poses = random_poses(rng, 40)
    write_tum(tmp_path / "p.tum", times, poses)
    t_back, p_back = read_tum(tmp_path / "p.tum")
    assert np.array_equal(t_back, times)
    assert np.array_equal(p_back[:, :3, 3], poses[:, :3, 3])
    np.testing.assert_allclose(p_back, poses, rtol=0, atol=1e-15 * 100)

    evo_traj = file_interface.read_tum_trajectory_file(str(tmp_path / "p.tum"))
    assert np.array_equal(evo_traj.timestamps, times)
    assert np.array_equal(evo_traj.positions_xyz, poses[:, :3, 3])
    np.testing.assert_allclose(np.array(evo_traj.poses_se3), poses, atol=1e-13)

    file_interface.write_tum_trajectory_file(
        str(tmp_path / "evo.tum"), PoseTrajectory3D(poses_se3=list(poses), timestamps=times)
    )
    t_evo, p_evo = read_tum(tmp_path / "evo.tum")
    assert np.array_equal(t_evo, times)
    assert np.array_equal(p_evo[:, :3, 3], poses[:, :3, 3])
    np.testing.assert_allclose(p_evo, poses, atol=1e-13)


@pytest.mark.parametrize(
    "line, message",
    [
        ("0.2 1 2 3 0 0 0", "expected 8 finite numbers"),
        ("0.2 1 2 3 0 0 0 1 5", "expected 8 finite numbers"),
        ("0.2 1 2 x 0 0 0 1", "expected 8 finite numbers"),
        ("0.2 1 2 nan 0 0 0 1", "expected 8 finite numbers"),
        ("0.2 1 2 3 0 0 0 0.9", "quaternion norm 0.9"),
        ("0.2 1 2 3 0 0 0 0", "quaternion norm 0"),
        ("0.1 1 2 3 0 0 0 1", r"time 0.1 does not increase \(previous 0.1\)"),  # no np.float64(...)
    ],
)
def test_bad_tum_lines_name_file_and_line(tmp_path: Path, line: str, message: str) -> None:
    text = "# time tx ty tz qx qy qz qw\n0.1 0 0 0 0 0 0 1\n\n" + line + "\n0.3 0 0 0 0 0 0 1\n"
    (tmp_path / "poses.tum").write_text(text)
    with pytest.raises(DatasetError, match=message) as err:
        read_tum(tmp_path / "poses.tum")
    assert "poses.tum:4" in str(err.value)


def test_tum_empty_or_missing(tmp_path: Path) -> None:
    (tmp_path / "e.tum").write_text("# only a comment\n")
    with pytest.raises(DatasetError, match="e.tum: no poses"):
        read_tum(tmp_path / "e.tum")
    with pytest.raises(DatasetError, match="missing.tum"):
        read_tum(tmp_path / "missing.tum")


def test_tum_accepts_nearly_unit_quaternions(tmp_path: Path) -> None:
    q = Rotation.from_euler("z", 0.3).as_quat()
    (tmp_path / "p.tum").write_text("0 1 2 3 " + " ".join(f"{v:.6f}" for v in q) + "\n")
    _, poses = read_tum(tmp_path / "p.tum")
    np.testing.assert_allclose(
        poses[0, :3, :3], Rotation.from_euler("z", 0.3).as_matrix(), atol=2e-6
    )
    np.testing.assert_allclose(poses[0, :3, :3] @ poses[0, :3, :3].T, np.eye(3), atol=1e-15)


def test_a_header_or_commas_are_named_as_such(tmp_path: Path) -> None:
    """One line before too, but naming only the bad line: a CSV export or a header line
    was left for the user to recognise."""
    path = tmp_path / "p.tum"
    path.write_text("timestamp tx ty tz qx qy qz qw\n0 0 0 0 0 0 0 1\n")
    with pytest.raises(DatasetError, match=r"p.tum:1: .*\(a header line\? a TUM file's comments"):
        read_tum(path)
    path.write_text("0, 0, 0, 0, 0, 0, 0, 1\n")
    with pytest.raises(DatasetError, match=r"p.tum:1: .*\(values separated by commas: a TUM"):
        read_tum(path)
    path.write_text("0 0 0 0 0 0 0 1\n1 x 0 0 0 0 0 1\n")  # a bad value: no hint
    with pytest.raises(DatasetError, match=r"p.tum:2: expected 8 finite numbers .*'$"):
        read_tum(path)
