"""A cloud topic whose clouds change layout mid-bag (a driver relaunched with other fields):
each cloud read in its own time field and unit, and the change noted; checked against the
room's true geometry."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bag_factory import (
    T0_NS,
    T_BASE,
    BagWriter,
    Truth,
    distance_to_room,
    lidar_cloud,
    true_pose,
    write_rig_and_odometry,
)

from planodom.datasets.bag_options import BagOptions
from planodom.datasets.rosbag import open_bag


def _without(bw: BagWriter, msg, name: str):
    """``msg`` without its field ``name`` (the bytes as they are)."""
    return bw.T["sensor_msgs/msg/PointCloud2"](
        header=msg.header,
        height=msg.height,
        width=msg.width,
        fields=[f for f in msg.fields if f.name != name],
        is_bigendian=False,
        point_step=msg.point_step,
        row_step=msg.row_step,
        data=msg.data,
        is_dense=False,
    )


def _bag(path: Path, ros: int, layouts: list[str], dropped: list[str | None]) -> None:
    """Sweeps on /points, sweep k in ``layouts[k]`` (:func:`lidar_cloud`) without the field
    ``dropped[k]``, with /tf_static and /odom."""
    truth = Truth(T_base_sensor=T_BASE)
    with BagWriter(path, ros) as bw:
        write_rig_and_odometry(bw, len(layouts) + 2)
        for k, (layout, name) in enumerate(zip(layouts, dropped, strict=True)):
            stamp = T0_NS + k * 100_000_000
            msg = lidar_cloud(bw, truth, "/points", "lidar", stamp, layout)
            bw.write("/points", msg if name is None else _without(bw, msg, name), stamp + 2_000_000)


def _read(path: Path) -> tuple[list[float], list[float], list[bool], list[str]]:
    """Per epoch: the largest distance of its points (placed by their times along the true
    trajectory) from the room, the span of its point times and whether it has rings; the
    notes."""
    with open_bag(path, BagOptions(gt_topic="/odom")) as ds:
        errors, spans, ringed = [], [], []
        for k in range(len(ds)):
            scan = ds[k]
            world = (
                true_pose(ds.times[k] + scan.t)
                @ np.append(scan.points, np.ones((len(scan), 1)), 1)[..., None]
            )
            errors.append(float(distance_to_room(world[:, :3, 0]).max()))
            spans.append(float(np.ptp(scan.t)))
            ringed.append(scan.ring is not None)
        return errors, spans, ringed, list(ds.notes)


def _path(tmp_path: Path, ros: int) -> Path:
    return tmp_path / ("layouts.bag" if ros == 1 else "layouts")


@pytest.mark.parametrize("ros", [1, 2])
@pytest.mark.parametrize("first, then", [("velodyne", "ouster"), ("ouster", "velodyne")])
def test_clouds_with_times_in_two_fields_are_each_read_in_their_own_unit(
    tmp_path: Path, ros: int, first: str, then: str
) -> None:
    # Velodyne's 'time' (float32 s), then Ouster's 't' (uint32 ns), or the other way: the
    # unit chosen for one field was applied to the other (float seconds scaled by 1e-9, the
    # sweeps deskewed as at one instant, or refused as 1e8 s off the stamp)
    _bag(_path(tmp_path, ros), ros, [first] * 3 + [then] * 3, [None] * 6)
    errors, spans, _, notes = _read(_path(tmp_path, ros))
    assert max(errors) < 1e-3  # 0.5 m when a sweep is not deskewed
    assert min(spans) > 0.09  # each sweep's 0.1 s
    (note,) = [n for n in notes if "fields or types" in n]
    assert "'time' (float32) in 3" in note and "'t' (uint32) in 3" in note


@pytest.mark.parametrize("ros", [1, 2])
def test_clouds_without_the_time_or_ring_field_of_the_others_are_noted(
    tmp_path: Path, ros: int
) -> None:
    _bag(_path(tmp_path, ros), ros, ["velodyne"] * 6, [None, None, "time", "time", "ring", None])
    errors, spans, ringed, notes = _read(_path(tmp_path, ros))
    assert max(errors[:2] + errors[4:]) < 1e-3
    assert spans[2] == spans[3] == 0.0  # taken at the stamp, as a cloud without times
    assert ringed == [True] * 4 + [False, True]
    assert any("2 of 6 clouds have no time field" in n for n in notes)
    assert any("1 of 6 clouds have no ring field" in n for n in notes)
