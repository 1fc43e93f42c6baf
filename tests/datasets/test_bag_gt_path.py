"""A ``nav_msgs/Path`` reference topic: a SLAM trajectory re-published whole as it grows."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bag_factory import STATIC_TF, T0_NS, T_BASE, Sensor, true_pose, write_bag

from planodom.datasets.bag_options import BagOptions
from planodom.datasets.rosbag import open_bag
from planodom.errors import DatasetError

STAMPS = [T0_NS - 100_000_000 + k * 5_000_000 for k in range(241)]  # as /odom's


def _path_bag(path: Path, ros: int, stamped: bool = True) -> None:
    """A bag whose /path re-publishes the trajectory so far every 0.3 s, 1 m off in x
    before its last message (a loop closure's correction), then an empty Path (a reset)."""

    def paths(bw) -> None:
        def pose(stamp: int, off: float):
            T = true_pose(stamp / 1e9)
            T[0, 3] += off
            t, q = bw.geometry(T)
            point = bw.T["geometry_msgs/msg/Point"](x=t[0], y=t[1], z=t[2])
            return bw.T["geometry_msgs/msg/PoseStamped"](
                header=bw.header(stamp if stamped else 0, ""),  # the Path's frame applies
                pose=bw.T["geometry_msgs/msg/Pose"](position=point, orientation=q),
            )

        ends = [T0_NS + k * 300_000_000 for k in range(4)] + [STAMPS[-1]]
        for i, end in enumerate(ends):
            off = 0.0 if i == len(ends) - 1 else 1.0
            poses = [pose(s, off) for s in STAMPS if s <= end]
            msg = bw.T["nav_msgs/msg/Path"](header=bw.header(end, "map"), poses=poses)
            bw.write("/path", msg, end + 1_000_000)
        empty = bw.T["nav_msgs/msg/Path"](header=bw.header(ends[-1], "map"), poses=[])
        bw.write("/path", empty, ends[-1] + 2_000_000)

    sensors = [Sensor("/points", "lidar", 0, "velodyne")]
    write_bag(path, ros, sensors, STATIC_TF, T_BASE, duration_s=1.0, extra=paths)


@pytest.mark.parametrize("ros", [1, 2])
def test_a_path_reference_is_read_from_its_last_message(tmp_path: Path, ros: int) -> None:
    """Refused before (``is nav_msgs/msg/Path, not one of ...``): now its last message with
    poses is the reference, each pose at its own stamp, the same as /odom's poses."""
    path = tmp_path / ("b.bag" if ros == 1 else "b")
    _path_bag(path, ros)
    with (
        open_bag(path, BagOptions(gt_topic="/path")) as ds,
        open_bag(path, BagOptions(gt_topic="/odom")) as odom,
    ):
        assert ds.gt_poses is not None and odom.gt_poses is not None
        np.testing.assert_allclose(ds.gt_poses, odom.gt_poses, atol=1e-9)
        assert ds.notes[0] == (
            "gt '/path': a nav_msgs/Path (a trajectory published whole): read from its last "
            "message with poses (recorded at 1700000001.101 s, 241 poses at "
            "their own stamps); its 5 other message(s) are left out"
        )
        assert "gt '/path': its poses in 'map' name no child frame" in ds.notes[1]
        assert len(ds.notes) == 2


def test_a_path_reference_without_pose_stamps_is_refused(tmp_path: Path) -> None:
    """A planner's Path leaves its poses unstamped: no time to read them at, one line."""
    _path_bag(tmp_path / "b", 2, stamped=False)
    with pytest.raises(DatasetError) as err:
        open_bag(tmp_path / "b", BagOptions(gt_topic="/path"))
    assert str(err.value) == (
        f"{tmp_path / 'b'}: topic '/path': 241 of the 241 poses of its last nav_msgs/Path "
        "message have no header stamp (0): a Path read as a reference needs each pose's time"
    )
