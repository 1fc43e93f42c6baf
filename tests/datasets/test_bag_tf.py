"""A bag's tf transforms with invalid values are ignored as tf2 ignores them: a quaternion
whose squared norm is 0.01 or more off 1 (``TF_DENORMALIZED_QUATERNION``), a zero or NaN one
(``TF_NAN_INPUT``). Read against the same bag with valid transforms (the room of
:mod:`bag_factory`, whose points are checked against the truth in ``test_rosbag.py``)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bag_factory import (
    STATIC_TF,
    T0_NS,
    T_BASE,
    BagWriter,
    Truth,
    lidar_cloud,
    pose,
    true_pose,
)
from scipy.spatial.transform import Rotation

from planodom.datasets.bag_options import BagOptions
from planodom.datasets.bag_tf import QUATERNION_NORM2_TOL, transform_from_msg
from planodom.datasets.rosbag import open_bag
from planodom.errors import DatasetError

Edit = Callable[..., Any]


def _bag(path: Path, ros: int, static: Edit | None = None, arm: Edit | None = None) -> None:
    """Five lidar sweeps on /points, /odom, /tf_static (:data:`STATIC_TF`, each transform
    passed through ``static``; none when it returns None for all) and, with ``arm``, a
    robot arm's moving frame on /tf (each of its five transforms ``k`` passed through
    ``arm(bw, tr, k)``)."""
    truth = Truth(T_base_sensor=T_BASE)
    with BagWriter(path, ros) as bw:
        tf = [bw.transform_stamped(T0_NS, *edge) for edge in STATIC_TF]
        tf = [static(bw, tr) for tr in tf] if static else tf
        if any(tr is not None for tr in tf):  # ``static`` returning None: no /tf_static
            bw.write("/tf_static", bw.tf(tf), T0_NS)
        for k in range(-1, 7):
            stamp = T0_NS + k * 100_000_000
            bw.write("/odom", bw.odometry(stamp, true_pose(stamp / 1e9)), stamp)
        for k in range(5):
            stamp = T0_NS + k * 100_000_000
            msg = lidar_cloud(bw, truth, "/points", "lidar", stamp)
            bw.write("/points", msg, stamp + 2_000_000)
            if arm is not None:
                at = stamp + 50_000_000
                link = pose(0.0, 0.0, 0.2 * k, (0.2, 0.0, 1.0))
                tr = arm(bw, bw.transform_stamped(at, "base_link", "arm_link", link), k)
                bw.write("/tf", bw.tf([tr]), at)


def _path(folder: Path, ros: int, name: str) -> Path:
    return folder / (f"{name}.bag" if ros == 1 else name)


def _rotation(bw: BagWriter, tr: Any, x: float, y: float, z: float, w: float) -> Any:
    q = bw.T["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)
    return replace(tr, transform=replace(tr.transform, rotation=q))


def _lidar_edge(tr: Any) -> bool:
    return tr.header.frame_id == "base_link" and tr.child_frame_id == "lidar"


def test_a_quaternion_is_normalised_within_tf2s_tolerance_only() -> None:
    """tf2 takes a quaternion whose squared norm lies less than 0.01 from 1 (and
    normalises it), and ignores one beyond: so does ``transform_from_msg``."""

    class Q:
        def __init__(self, s: float) -> None:
            q = Rotation.from_euler("xyz", [0.1, 0.2, 0.3]).as_quat() * s
            self.x, self.y, self.z, self.w = q

    class V:
        x, y, z = 1.0, 2.0, 3.0

    R = Rotation.from_euler("xyz", [0.1, 0.2, 0.3]).as_matrix()
    inside = np.sqrt(1 + 0.99 * QUATERNION_NORM2_TOL)
    for s in (1.0, inside, 1 / inside):
        np.testing.assert_allclose(transform_from_msg(V, Q(s))[:3, :3], R, atol=1e-12)
    for s in (np.sqrt(1 + 1.01 * QUATERNION_NORM2_TOL), np.sqrt(1 - 1.01 * QUATERNION_NORM2_TOL)):
        with pytest.raises(ValueError, match="no unit quaternion"):
            transform_from_msg(V, Q(s))


@pytest.mark.parametrize("ros", [1, 2])
def test_angles_written_as_a_quaternion_refuse_the_extrinsic(tmp_path: Path, ros: int) -> None:
    """The lidar's mount given as roll, pitch, yaw and 1 in the quaternion's slots (a
    ``static_transform_publisher`` given angles where a quaternion goes): tf2 ignores it;
    planodom normalised it to a rotation of 33.8 deg for the mount's 17.4 (16.4 deg off)
    and read the bag with it, without a word. The extrinsic is now missing, and the error
    says why."""
    roll, pitch, yaw = Rotation.from_matrix(T_BASE["lidar"][:3, :3]).as_euler("xyz")

    def angles(bw: BagWriter, tr: Any) -> Any:
        return _rotation(bw, tr, roll, pitch, yaw, 1.0) if _lidar_edge(tr) else tr

    _bag(_path(tmp_path, ros, "angles"), ros, static=angles)
    with pytest.raises(DatasetError) as err:
        open_bag(_path(tmp_path, ros, "angles"))
    message = str(err.value)
    assert "\n" not in message
    assert "no transform from frame 'lidar' to base frame 'base_link'" in message
    assert "/tf_static: 1 transform(s) 'base_link' -> 'lidar' ignored, as tf2 ignores" in message
    assert "of norm 1.045 is no unit quaternion" in message


@pytest.mark.parametrize("ros", [1, 2])
def test_a_quaternion_rounded_off_unit_length_is_read(tmp_path: Path, ros: int) -> None:
    """A quaternion written with few digits (squared norm 1.009, inside tf2's tolerance)
    is normalised: the same extrinsic as the exact one's, to 1e-12."""
    scale = np.sqrt(1.009)

    def rounded(bw: BagWriter, tr: Any) -> Any:
        if not _lidar_edge(tr):
            return tr
        q = tr.transform.rotation
        return _rotation(bw, tr, q.x * scale, q.y * scale, q.z * scale, q.w * scale)

    _bag(_path(tmp_path, ros, "rounded"), ros, static=rounded)
    _bag(_path(tmp_path, ros, "clean"), ros)
    with (
        open_bag(_path(tmp_path, ros, "rounded")) as ds,
        open_bag(_path(tmp_path, ros, "clean")) as clean,
    ):
        np.testing.assert_allclose(ds.rig.extrinsics[0], clean.rig.extrinsics[0], atol=1e-12)
        assert ds.notes == clean.notes == []


@pytest.mark.parametrize("ros", [1, 2])
def test_invalid_transforms_of_a_frame_not_needed_are_ignored(tmp_path: Path, ros: int) -> None:
    """A robot arm's frame on /tf, its servo reporting NaN, a zero and a denormalised
    quaternion for three of its five transforms (tf2 ignores them; navigation is
    untouched): the bag was refused (`invalid quaternion [nan, ...]`). Those transforms are
    ignored and noted; the bag reads as the one whose arm transforms are all valid."""

    def servo(bw: BagWriter, tr: Any, k: int) -> Any:
        bad = {1: (np.nan,) * 4, 2: (0.0,) * 4, 3: (0.0, 0.0, 0.5, 2.0)}
        return _rotation(bw, tr, *bad[k]) if k in bad else tr

    _bag(_path(tmp_path, ros, "servo"), ros, arm=servo)
    _bag(_path(tmp_path, ros, "clean"), ros, arm=lambda bw, tr, k: tr)
    opts = BagOptions(gt_topic="/odom")
    with (
        open_bag(_path(tmp_path, ros, "servo"), opts) as ds,
        open_bag(_path(tmp_path, ros, "clean"), opts) as clean,
    ):
        assert clean.notes == []
        assert ds.notes == [
            "/tf: 3 transform(s) 'base_link' -> 'arm_link' ignored, as tf2 ignores them (the "
            "first: invalid quaternion [nan, nan, nan, nan])"
        ]
        np.testing.assert_array_equal(ds.gt_poses, clean.gt_poses)
        np.testing.assert_array_equal(ds.rig.extrinsics[0], clean.rig.extrinsics[0])
        np.testing.assert_array_equal(ds.times, clean.times)
        for scan, other in zip(ds, clean, strict=True):
            np.testing.assert_array_equal(scan.points, other.points)
            np.testing.assert_array_equal(scan.t, other.t)


@pytest.mark.parametrize("ros", [1, 2])
def test_a_bag_without_static_transforms_is_said(tmp_path: Path, ros: int) -> None:
    """A recording started after the static transform publishers, their latched /tf_static
    messages missed: the error offered only another base frame, no way out for a rig of
    several sensors. It now says the bag holds no /tf_static transform."""
    _bag(_path(tmp_path, ros, "none"), ros, static=lambda bw, tr: None)
    with pytest.raises(DatasetError) as err:
        open_bag(_path(tmp_path, ros, "none"))
    message = str(err.value)
    assert "\n" not in message
    assert message.endswith(
        "; the bag holds no /tf_static transform (a recording started after the static "
        "transform publishers can miss their latched messages): add them to the bag"
    )
