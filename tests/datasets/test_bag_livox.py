"""Livox CustomMsg bags (ROS 1 and ROS 2), written with rosbags and read back exactly."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import numpy as np
import pytest
from bag_factory import T0_NS, BagWriter, pose

from planodom.datasets.bag_livox import LIVOX_CUSTOM, livox_types
from planodom.datasets.bag_options import BagOptions
from planodom.datasets.rosbag import open_bag
from planodom.errors import DatasetError

T_BASE_LIVOX = pose(0.0, 0.1, 0.05, (0.3, 0.0, 1.2))


def _custom_msg(
    bw: BagWriter, msgtype: str, stamp: int, xyz, line, offset, point_num=None, tags=None
):
    package = msgtype.split("/")[0]
    Point = bw.T[f"{package}/msg/CustomPoint"]
    tags = np.zeros(len(xyz), np.uint8) if tags is None else tags
    points = [
        Point(offset_time=int(o), x=float(p[0]), y=float(p[1]), z=float(p[2]),
              reflectivity=10, tag=int(g), line=int(r))
        for p, r, o, g in zip(xyz, line, offset, tags, strict=True)
    ]  # fmt: skip
    return bw.T[msgtype](
        header=bw.header(stamp, "livox_frame"),
        timebase=stamp - 3_000,  # the driver's timebase: a few us before the stamp
        point_num=len(points) if point_num is None else point_num,
        lidar_id=0,
        rsvd=np.zeros(3, np.uint8),
        points=points,
    )


def _write(
    path: Path, ros: int, msgtype: str, sweeps: list, point_num=None, old=False, tags=None
) -> None:
    with BagWriter(path, ros) as bw:
        bw.ts.register(livox_types())
        bw.T = bw.ts.types
        tf = bw.tf([bw.transform_stamped(T0_NS, "base_link", "livox_frame", T_BASE_LIVOX)])
        bw.write("/tf_static", tf, T0_NS)
        for k, (xyz, line, offset) in enumerate(sweeps):
            stamp = T0_NS + k * 100_000_000
            msg = _custom_msg(bw, msgtype, stamp, xyz, line, offset, point_num, tags)
            bw.write("/livox/lidar", msg, stamp + 1_000_000)
    if old:  # as a bag of ROS 2 Humble or older: no message definitions stored
        with sqlite3.connect(next(path.glob("*.db3"))) as db:
            db.execute("DELETE FROM message_definitions")


def _sweeps(rng: np.random.Generator, n: int = 3, points: int = 50) -> list:
    out = []
    for _ in range(n):
        xyz = rng.uniform(-20, 20, (points, 3)).astype(np.float32)
        xyz[7] = 0.0  # a no-return
        out.append((xyz, rng.integers(0, 6, points), np.sort(rng.integers(0, 99_000_000, points))))
    return out


@pytest.mark.parametrize(
    "ros, msgtype, old",
    [(1, LIVOX_CUSTOM[0], False), (2, LIVOX_CUSTOM[1], False), (2, LIVOX_CUSTOM[1], True)],
)
def test_livox_custom_messages_read_exactly(
    tmp_path: Path, ros: int, msgtype: str, old: bool
) -> None:
    sweeps = _sweeps(np.random.default_rng(ros))
    path = tmp_path / ("l.bag" if ros == 1 else "l")
    _write(path, ros, msgtype, sweeps, old=old)
    with open_bag(path, BagOptions()) as ds:
        assert len(ds) == 3 and [t.msgtype for t in ds.topics] == [msgtype]
        for k, (xyz, line, offset) in enumerate(sweeps):
            scan, keep = ds[k], np.any(xyz != 0, axis=1)
            R, t = T_BASE_LIVOX[:3, :3], T_BASE_LIVOX[:3, 3]
            order = np.argsort(line[keep], kind="stable")  # the reader sorts by ring
            expected = (xyz[keep].astype(np.float64) @ R.T + t)[order]
            assert np.abs(scan.points - expected).max() < 1e-12
            assert np.array_equal(scan.ring, line[keep][order])
            assert scan.t == pytest.approx((offset[keep][order] - 3_000) * 1e-9, abs=1e-12)
        assert ds.rig.sensor_origins.shape == (6, 3)


def test_livox_point_num_that_does_not_match(tmp_path: Path) -> None:
    _write(tmp_path / "bad", 2, LIVOX_CUSTOM[1], _sweeps(np.random.default_rng(0), 1), 51)
    with pytest.raises(DatasetError, match=r"bad: topic '/livox/lidar': .*point_num 51 .* 50"):
        with open_bag(tmp_path / "bad", BagOptions()) as ds:
            ds[0]


@pytest.mark.parametrize("ros, msgtype", [(1, LIVOX_CUSTOM[0]), (2, LIVOX_CUSTOM[1])])
def test_points_the_lidar_marks_as_noise_are_left_out(tmp_path: Path, ros: int, msgtype) -> None:
    """Points whose tag says "high confidence noise" (01 in bits 1-0, spatial, or in bits
    3-2, intensity) were kept: the bag reads as the one where they are no returns, noted;
    moderate and low confidence noise (10, 11) and the return-number bits 5-4 are kept."""
    sweeps = _sweeps(np.random.default_rng(5))
    tags = np.zeros(50, np.uint8)
    tags[[3, 11, 20]] = [0b01, 0b0100, 0b010101]  # high confidence noise: left out
    tags[[4, 12, 30, 31]] = [0b10, 0b11, 0b1000, 0b010000]  # kept
    blanked = [(np.where(np.isin(np.arange(50), [3, 11, 20])[:, None], 0.0, x).astype(np.float32),
                r, o) for x, r, o in sweeps]  # fmt: skip
    name = "n.bag" if ros == 1 else "n"
    _write(tmp_path / name, ros, msgtype, sweeps, tags=tags)
    _write(tmp_path / ("c" + name), ros, msgtype, blanked)
    with open_bag(tmp_path / name) as ds, open_bag(tmp_path / ("c" + name)) as clean:
        for scan, truth in zip(ds, clean, strict=True):
            np.testing.assert_array_equal(scan.points, truth.points)
            np.testing.assert_array_equal(scan.ring, truth.ring)
            np.testing.assert_array_equal(scan.t, truth.t)
        assert clean.notes == []
        assert ds.notes == [
            "topic '/livox/lidar': 9 points the Livox lidar marks as high confidence noise "
            "(its tag: rain, dust, a return on the window?); left out"
        ]
