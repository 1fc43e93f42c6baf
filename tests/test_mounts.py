"""Sensor mounts far from the base frame's origin: refused beyond any vehicle's length
(an extrinsic in millimetres, a base frame not on the vehicle), noted beyond a lorry's.
Read from a dataset's rig.yaml, a bag's tf and a KITTI calib.txt; the bounds are vehicle
sizes (:mod:`planodom.mounts`)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bag_factory import STATIC_TF, T0_NS, T_BASE, BagWriter, Truth, lidar_cloud, true_pose
from typer.testing import CliRunner

from planodom.cli import app
from planodom.datasets.dataset import load_dataset
from planodom.datasets.kitti import read_kitti_calib
from planodom.datasets.rosbag import open_bag
from planodom.errors import DatasetError
from planodom.mounts import MOUNT_LIMIT_M, MOUNT_NOTE_M, check_mounts
from planodom.rig import Rig

runner = CliRunner()


def test_the_bounds_split_millimetres_from_vehicles() -> None:
    """A lidar 1.6 m up written in millimetres is refused; a rig's metres pass, a mount
    between the two bounds is noted, once for several."""
    assert check_mounts([("a", np.array([0.1, 0.0, 1.6]))], "") == []
    with pytest.raises(
        DatasetError, match=r"^a: translation \(100, 0, 1600\) puts the sensor 1603 m"
    ):
        check_mounts([("a", np.array([100.0, 0.0, 1600.0]))], "")
    far = np.array([0.0, MOUNT_NOTE_M + 1.0, 0.0])
    notes = check_mounts([("b", far), ("c", far)], "; hint")
    assert len(notes) == 1 and notes[0].startswith("b: translation (0, 26, 0)")
    assert notes[0].endswith("; hint")
    assert MOUNT_NOTE_M < MOUNT_LIMIT_M


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("sim") / "ds"
    result = runner.invoke(app, ["simulate", "--out", str(path), "--epochs", "3"])
    assert result.exit_code == 0, result.output
    return path


def _rig_yaml(ds: Path, scale: float) -> Path:
    """``ds``'s rig.yaml with its sensor origins times ``scale`` (1000: millimetres)."""
    import yaml

    rig = yaml.safe_load((ds / "rig.yaml").read_text())
    rig["sensor_origins"] = (np.asarray(rig["sensor_origins"]) * scale).tolist()
    (ds / "rig.yaml").write_text(yaml.safe_dump(rig))
    return ds / "rig.yaml"


def test_rig_yaml_in_millimetres_is_refused_naming_the_field(
    simulated: Path, tmp_path: Path
) -> None:
    """Read before: the normals oriented towards sensors kilometres away, no word."""
    import shutil

    ds = Path(shutil.copytree(simulated, tmp_path / "ds"))
    path = _rig_yaml(ds, 1000.0)
    result = runner.invoke(app, ["run", str(ds), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2, result.output
    line = result.stderr.strip()
    assert line.startswith(f"error: {path}: field 'sensor_origins.0': translation (")
    assert "millimetres?" in line and "\n" not in line
    assert not (tmp_path / "out").exists()


def test_rig_yaml_extrinsics_are_checked_and_metres_read_as_before(simulated: Path) -> None:
    T = np.eye(4)
    T[:3, 3] = [1200.0, 0.0, 1800.0]
    with pytest.raises(
        DatasetError, match=r"^rig.yaml: field 'extrinsics.0': translation \(1200, 0, 1800\)"
    ):
        Rig.from_dict({"extrinsics": [T.tolist()]})
    ds = load_dataset(simulated)  # the simulated rig: metres, within a vehicle
    assert not [n for n in ds.notes if "base frame's origin" in n]


def test_rig_yaml_mount_beyond_a_lorry_is_noted(simulated: Path, tmp_path: Path) -> None:
    import shutil

    ds = Path(shutil.copytree(simulated, tmp_path / "ds"))
    path = _rig_yaml(ds, 40.0)  # the paper's rig's mounts, about 1 m: now about 40 m
    notes = [n for n in load_dataset(ds).notes if "base frame's origin" in n]
    assert len(notes) == 1 and notes[0].startswith(f"{path}: field 'sensor_origins.")


def _bag(path: Path, scale: float) -> None:
    """Three lidar sweeps on /points with /tf_static's base_link -> lidar translation times
    ``scale`` (the points written in the lidar's frame as for the true mount)."""
    truth = Truth(T_base_sensor=T_BASE)
    with BagWriter(path, 2) as bw:
        tf = [bw.transform_stamped(T0_NS, *edge) for edge in STATIC_TF]
        for i, tr in enumerate(tf):
            if tr.header.frame_id == "base_link" and tr.child_frame_id == "lidar":
                t = tr.transform.translation
                moved = replace(t, x=t.x * scale, y=t.y * scale, z=t.z * scale)
                tf[i] = replace(tr, transform=replace(tr.transform, translation=moved))
        bw.write("/tf_static", bw.tf(tf), T0_NS)
        for k in range(-1, 5):
            stamp = T0_NS + k * 100_000_000
            bw.write("/odom", bw.odometry(stamp, true_pose(stamp / 1e9)), stamp)
        for k in range(3):
            stamp = T0_NS + k * 100_000_000
            bw.write("/points", lidar_cloud(bw, truth, "/points", "lidar", stamp), stamp + 1)


def test_a_bag_transform_in_millimetres_is_refused_naming_it(tmp_path: Path) -> None:
    """Read before: the points 1.6 km up, every epoch unresolved, the reason unsaid."""
    _bag(tmp_path / "mm", 1000.0)
    expected = (
        rf"^{tmp_path / 'mm'}: topic '/points': transform 'base_link' -> 'lidar': "
        r"translation \(100, 0, 1600\) puts the sensor 1603 m .* millimetres\? .*--base-frame"
    )
    with pytest.raises(DatasetError, match=expected):
        open_bag(tmp_path / "mm")
    _bag(tmp_path / "far", 30.0)  # 48 m: read, noted
    with open_bag(tmp_path / "far") as ds:
        notes: list[Any] = [n for n in ds.notes if "base frame's origin" in n]
    assert len(notes) == 1 and "'base_link' -> 'lidar'" in notes[0]
    _bag(tmp_path / "m", 1.0)
    with open_bag(tmp_path / "m") as ds:
        assert not [n for n in ds.notes if "base frame's origin" in n]


def test_a_kitti_calib_in_millimetres_is_refused(tmp_path: Path) -> None:
    rows = "0 -1 0 -4.07 0 0 -1 -76.3 1 0 0 -271.8"  # KITTI 00's Tr, translation in mm
    (tmp_path / "calib.txt").write_text(f"P0: {' '.join(['0'] * 12)}\nTr: {rows}\n")
    with pytest.raises(
        DatasetError, match=r"calib.txt:2: 'Tr': translation \(-4.07, -76.3, -271.8\)"
    ):
        read_kitti_calib(tmp_path / "calib.txt")
    (tmp_path / "calib.txt").write_text("Tr: 0 -1 0 -0.004 0 0 -1 -0.076 1 0 0 -0.27\n")
    assert np.allclose(read_kitti_calib(tmp_path / "calib.txt")[:3, 3], [-0.004, -0.076, -0.27])
