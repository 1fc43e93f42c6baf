"""The parts of the bag reader checked by hand: epochs, interpolation, time fields, tf chains."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace as NS

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planodom.datasets.bag_epochs import group_epochs, interpolate_poses, window_phase
from planodom.datasets.bag_msgs import POINT_CLOUD2, decode_sweep, tagged_noise
from planodom.datasets.bag_tf import TfTree
from planodom.errors import DatasetError

MS = 1_000_000


def test_jittered_scanners_never_straddle_a_window() -> None:
    # scanners at phases 0, 25, 50 ms of a 100 ms period with +-2 ms jitter: the windows
    # start mid of the largest phase gap (52..98 ms -> 75 ms), so each epoch gets one sweep
    # of each scanner even though scanner 0 jitters around the period's zero
    rng = np.random.default_rng(3)
    base = 1_700_000_000_000 * MS
    stamps, owner = [], []
    for k in range(50):
        for s, phase in enumerate((0, 25, 50)):
            stamps.append(base + k * 100 * MS + phase * MS + int(rng.integers(-2 * MS, 2 * MS)))
            owner.append(s)
    stamps_a = np.array(stamps)
    phase = window_phase(stamps_a, 100 * MS)
    assert 70 * MS < phase < 80 * MS
    members, ref = group_epochs(stamps_a, 100 * MS)
    assert len(members) == 50
    for idx in members:
        assert sorted(np.array(owner)[idx].tolist()) == [0, 1, 2]
    # the reference is the middle scanner's sweep (closest to the window centre, 25 ms)
    assert [int(np.array(owner)[members[e][np.argmax(stamps_a[members[e]] == ref[e])]])
            for e in range(50)] == [1] * 50  # fmt: skip
    assert np.all(np.diff(ref) > 0)


def test_interpolation_by_hand() -> None:
    T0, T1 = np.eye(4), np.eye(4)
    T1[:3, :3] = Rotation.from_euler("z", 0.8).as_matrix()
    T1[:3, 3] = [2.0, -4.0, 1.0]
    times = np.array([10 * MS, 20 * MS])
    inside, poses = interpolate_poses(
        times, np.stack([T0, T1]), np.array([5, 15, 17.5, 20, 21]) * MS
    )
    assert inside.tolist() == [False, True, True, True, False]
    assert np.allclose(poses[0, :3, 3], [1.0, -2.0, 0.5])
    assert np.allclose(Rotation.from_matrix(poses[0, :3, :3]).as_rotvec(), [0, 0, 0.4])
    assert np.allclose(Rotation.from_matrix(poses[1, :3, :3]).as_rotvec(), [0, 0, 0.6])
    assert np.allclose(poses[2], T1)


def cloud(fields: list[tuple[str, int, int]], rows: np.ndarray, step: int, stamp_ns: int) -> NS:
    """A PointCloud2-like message (unorganised) from a structured array."""
    return NS(
        header=NS(stamp=NS(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9), frame_id="lidar"),
        height=1, width=len(rows), is_bigendian=False, point_step=step, row_step=step * len(rows),
        fields=[NS(name=n, offset=o, datatype=c, count=1) for n, o, c in fields],
        data=np.frombuffer(rows.tobytes(), dtype=np.uint8),
    )  # fmt: skip


def test_absolute_float_timestamps_hesai() -> None:
    stamp = 1_700_000_000 * 10**9 + 500 * MS
    dtype = np.dtype({"names": ["x", "y", "z", "timestamp", "ring"],
                      "formats": ["<f4", "<f4", "<f4", "<f8", "<u2"],
                      "offsets": [0, 4, 8, 16, 24], "itemsize": 32})  # fmt: skip
    rows = np.zeros(3, dtype=dtype)
    rows["x"] = [1.0, 2.0, np.nan]
    rows["timestamp"] = [1_700_000_000.5, 1_700_000_000.5625, 1_700_000_000.6]
    rows["ring"] = [3, 0, 1]
    fields = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("timestamp", 16, 8), ("ring", 24, 4)]
    pts, ring, dt, rings = decode_sweep(cloud(fields, rows, 32, stamp), POINT_CLOUD2)
    assert pts.tolist() == [[1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]  # the NaN point is dropped
    assert ring.tolist() == [3, 0] and rings == 4
    assert dt == pytest.approx([0.0, 0.0625], abs=1e-6)


def test_relative_ns_offsets_livox() -> None:
    dtype = np.dtype({"names": ["x", "y", "z", "offset_time"],
                      "formats": ["<f4", "<f4", "<f4", "<u4"],
                      "offsets": [0, 4, 8, 12], "itemsize": 16})  # fmt: skip
    rows = np.zeros(2, dtype=dtype)
    rows["y"] = [1.0, 0.0]
    rows["offset_time"] = [0, 12_345_678]
    fields = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("offset_time", 12, 6)]
    pts, ring, dt, rings = decode_sweep(cloud(fields, rows, 16, 10**18), POINT_CLOUD2)
    # the all-zero second point is a no-return marker and is dropped
    assert pts.tolist() == [[0.0, 1.0, 0.0]] and ring is None and rings == 0
    assert dt.tolist() == [0.0]
    rows["x"] = [0.0, 5.0]
    _, _, dt, _ = decode_sweep(cloud(fields, rows, 16, 10**18), POINT_CLOUD2)
    assert dt.tolist() == [0.0, 0.012345678]


def _livox2_cloud(timestamps: list[float], stamp: int, tags=None) -> NS:
    """livox_ros_driver2's PointCloud2 layout: ``line`` uint8, ``timestamp`` float64."""
    dtype = np.dtype({"names": ["x", "y", "z", "intensity", "tag", "line", "timestamp"],
                      "formats": ["<f4", "<f4", "<f4", "<f4", "u1", "u1", "<f8"],
                      "offsets": [0, 4, 8, 12, 16, 17, 18], "itemsize": 26})  # fmt: skip
    rows = np.zeros(len(timestamps), dtype=dtype)
    rows["x"] = np.arange(1, len(timestamps) + 1)
    rows["line"] = np.arange(len(timestamps)) % 6
    rows["timestamp"] = timestamps
    rows["tag"] = 0 if tags is None else tags
    fields = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("intensity", 12, 7), ("tag", 16, 2),
              ("line", 17, 2), ("timestamp", 18, 8)]  # fmt: skip
    return cloud(fields, rows, 26, stamp)


def test_absolute_double_nanoseconds_livox_driver2() -> None:
    stamp = 1_700_000_000 * 10**9 + 250 * MS
    ns = [stamp + 0.0, stamp + 40 * MS, stamp + 99 * MS]
    pts, ring, dt, rings = decode_sweep(_livox2_cloud(ns, stamp), POINT_CLOUD2)
    assert ring.tolist() == [0, 1, 2] and rings == 3
    assert dt == pytest.approx([0.0, 0.040, 0.099], abs=1e-6)  # float64 ns: 256 ns steps


def test_livox_pointcloud2_points_marked_noise_are_left_out() -> None:
    """The tag of livox_ros_driver2's PointCloud2 as of its CustomMsg: high confidence
    noise (01 in bits 1-0 or 3-2) left out, moderate noise (10) kept."""
    stamp = 1_700_000_000 * 10**9
    msg = _livox2_cloud([stamp + k * MS for k in range(5)], stamp, [0, 0b01, 0b10, 0b0100, 0])
    pts, ring, _, _ = decode_sweep(msg, POINT_CLOUD2)
    assert pts[:, 0].tolist() == [1.0, 3.0, 5.0] and ring.tolist() == [0, 2, 4]
    assert tagged_noise(msg, POINT_CLOUD2) == 2


@pytest.mark.parametrize(
    "times, shown",
    [([0.0, 50.0, 99.0], "puts a point 99 s"), ([0.0, np.nan, 0.01], "is NaN at 1 of 3 points")],
)
def test_times_in_another_unit_are_refused_naming_the_field(times: list, shown: str) -> None:
    """Float milliseconds read as seconds would make a 99 s sweep; NaN times are no times
    (said as such: "puts a point nan s from the stamp ... not seconds" blamed the unit)."""
    with pytest.raises(ValueError, match=rf"time field 'timestamp' \(float64\) {shown}"):
        decode_sweep(_livox2_cloud(times, 10**18), POINT_CLOUD2)


@pytest.mark.parametrize("ring_name, code", [("ring", 8), ("channel", 6)])
def test_nebula_time_stamp_field(ring_name: str, code: int) -> None:
    """TIER IV's nebula drivers: XYZIRADT with ``ring`` and ``time_stamp`` absolute float64
    seconds; XYZIRCAEDT with ``channel`` and ``time_stamp`` uint32 ns offsets."""
    stamp = 1_673_400_472 * 10**9 + 138 * MS
    fmt = "<f8" if code == 8 else "<u4"
    dtype = np.dtype({"names": ["x", "y", "z", ring_name, "time_stamp"],
                      "formats": ["<f4", "<f4", "<f4", "<u2", fmt],
                      "offsets": [0, 4, 8, 12, 16], "itemsize": 24})  # fmt: skip
    rows = np.zeros(2, dtype=dtype)
    rows["x"], rows[ring_name] = [1.0, 2.0], [5, 9]
    offsets_ns = np.array([1_000, 55_500_000])
    rows["time_stamp"] = (stamp + offsets_ns) * 1e-9 if code == 8 else offsets_ns
    fields = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), (ring_name, 12, 4), ("time_stamp", 16, code)]
    _, ring, dt, rings = decode_sweep(cloud(fields, rows, 24, stamp), POINT_CLOUD2)
    assert ring.tolist() == [5, 9] and rings == 10
    assert dt == pytest.approx(offsets_ns * 1e-9, abs=1e-6)


def test_cloud_that_does_not_fit_its_data() -> None:
    rows = np.zeros(2, dtype=np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4")]))
    msg = cloud([("x", 0, 7), ("y", 4, 7), ("z", 8, 7)], rows, 12, 0)
    msg.width = 5
    with pytest.raises(ValueError, match="does not fit"):
        decode_sweep(msg, POINT_CLOUD2)


def test_a_field_of_several_values_or_beyond_the_point_is_refused_naming_it() -> None:
    """A time field of count 2 gave twice as many times as points, refused deep in ``Scan``
    without the bag, topic or field ("scan field 't' has 6 values for 3 points"); a field
    past the point's end, in numpy's words ("dtype descriptor requires 24 bytes")."""
    dtype = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("time", "<f4", 2)])
    rows = np.zeros(3, dtype=dtype)
    rows["x"] = [1.0, 2.0, 3.0]
    msg = cloud([("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("time", 12, 7)], rows, 20, 0)
    msg.fields[3].count = 2
    with pytest.raises(ValueError, match=r"^PointCloud2 field 'time' has count 2, not 1 value"):
        decode_sweep(msg, POINT_CLOUD2)
    msg.fields[3].count = 1  # a single time is read
    assert decode_sweep(msg, POINT_CLOUD2)[2].tolist() == [0.0, 0.0, 0.0]
    msg.fields[3].offset = 18
    with pytest.raises(
        ValueError, match=r"^PointCloud2 field 'time' \(4 bytes at offset 18\) does not fit its"
    ):
        decode_sweep(msg, POINT_CLOUD2)


def test_cloud_with_integer_coordinates_is_refused_naming_the_field() -> None:
    """int16 millimetres (or a uint8 x) were read as metres, a cloud of garbage."""
    rows = np.zeros(2, dtype=np.dtype([("x", "<f4"), ("y", "<i2"), ("z", "<f4")]))
    rows["y"] = [1200, -300]
    msg = cloud([("x", 0, 7), ("y", 4, 3), ("z", 6, 7)], rows, 10, 0)
    with pytest.raises(ValueError, match=r"^PointCloud2 coordinate field 'y' is int16, not a"):
        decode_sweep(msg, POINT_CLOUD2)


def tf_msg(parent: str, child: str, xyz: tuple[float, float, float], yaw: float = 0.0) -> NS:
    q = Rotation.from_euler("z", yaw).as_quat()
    tr = NS(translation=NS(x=xyz[0], y=xyz[1], z=xyz[2]),
            rotation=NS(x=q[0], y=q[1], z=q[2], w=q[3]))  # fmt: skip
    header = NS(frame_id=parent, stamp=NS(sec=1, nanosec=0))
    return NS(transforms=[NS(header=header, child_frame_id=child, transform=tr)])


def test_tf_chain_up_and_down_and_moving_edges() -> None:
    tree = TfTree()
    tree.add(tf_msg("/base_footprint", "base_link", (0.0, 0.0, 0.5)), static=True)
    tree.add(tf_msg("base_footprint", "laser", (1.0, 0.0, 0.0), math.pi / 2), static=True)
    tree.add(tf_msg("odom", "base_footprint", (0.0, 0.0, 0.0)), static=False)
    tree.add(tf_msg("odom", "base_footprint", (0.1, 0.0, 0.0)), static=False)
    tree.add(tf_msg("base_link", "cam", (0.0, 2.0, 0.0)), static=False)
    tree.add(tf_msg("base_link", "cam", (0.0, 2.0, 0.0)), static=False)
    # laser in base_link: up to base_footprint (+1 x) and down to base_link (-0.5 z)
    T = tree.require("base_link", "laser", "bag")
    assert np.allclose(T[:3, 3], [1.0, 0.0, -0.5])
    assert np.allclose(T[:3, :3], Rotation.from_euler("z", math.pi / 2).as_matrix())
    assert np.allclose(tree.lookup("base_link", "cam")[:3, 3], [0.0, 2.0, 0.0])  # rigid /tf
    assert tree.lookup("base_link", "odom") is None  # odom -> base_footprint moves
    with pytest.raises(DatasetError, match="'odom'.*moving /tf"):
        tree.require("base_link", "odom", "bag: topic '/x'")


def test_a_loop_in_the_tf_tree_is_said_with_its_disagreement() -> None:
    """A frame published under a second parent closes a loop: the extrinsic silently took
    one of the two chains. The chains' disagreement is said (a loop that agrees is not)."""
    tree = TfTree()
    tree.add(tf_msg("base_link", "mount", (0.0, 0.0, 1.0)), static=True)
    tree.add(tf_msg("mount", "lidar", (0.5, 0.0, 0.0)), static=True)
    assert tree.loops("base_link") == []
    tree.add(tf_msg("base_link", "lidar", (0.5, 0.0, 1.0005)), static=True)  # agrees to 0.5 mm
    assert tree.loops("base_link") == []
    tree.add(tf_msg("base_link", "lidar", (0.5, 0.0, 0.9), 0.1), static=True)
    T = tree.lookup("base_link", "lidar")  # the direct edge: the chain of fewest links
    assert np.allclose(T[:3, 3], [0.5, 0.0, 0.9])
    (line,) = tree.loops("base_link")
    assert line == (
        "/tf_static or /tf: frames 'mount' and 'lidar' are joined by a transform and by "
        "another chain that differ by 0.100 m and 5.73 deg (a loop in the tf tree: a frame "
        "published under two parents?); transforms from 'base_link' take the chain of fewest "
        "links"
    )
    assert tree.loops("elsewhere") == []  # not joined to base_link's frames


def test_files_dropped_beside_a_bag_are_not_bags(tmp_path: Path) -> None:
    from planodom.datasets.bag_paths import is_bag

    (tmp_path / "x.db3").write_bytes(b"")
    assert not is_bag(tmp_path) and not is_bag(tmp_path / "x.db3")


def test_time_field_option_none_named_and_missing() -> None:
    """A sensor clock that is not the stamps' (nebula's Hesai scans: 1.7e8 s off) is refused
    with the way out; ``none`` ignores it; a named field is read instead of the first."""
    stamp = 1_673_401_196 * 10**9
    dtype = np.dtype({"names": ["x", "y", "z", "t", "time_stamp"],
                      "formats": ["<f4", "<f4", "<f4", "<f4", "<f8"],
                      "offsets": [0, 4, 8, 12, 16], "itemsize": 24})  # fmt: skip
    rows = np.zeros(2, dtype=dtype)
    rows["x"], rows["t"] = [1.0, 2.0], [0.0, 0.05]
    rows["time_stamp"] = [1_504_708_283.0, 1_504_708_283.02]  # the lidar's own clock
    fields = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("t", 12, 7), ("time_stamp", 16, 8)]
    msg = cloud(fields, rows, 24, stamp)
    assert decode_sweep(msg, POINT_CLOUD2)[2] == pytest.approx([0.0, 0.05])  # auto: 't'
    with pytest.raises(ValueError, match="'time_stamp' .*--time-field none ignores it"):
        decode_sweep(msg, POINT_CLOUD2, "time_stamp")
    assert decode_sweep(msg, POINT_CLOUD2, "none")[2].tolist() == [0.0, 0.0]
    with pytest.raises(ValueError, match="no time field 'offset_time' .*x, y, z, t, time_stamp"):
        decode_sweep(msg, POINT_CLOUD2, "offset_time")


def test_dual_return_cloud_keeps_the_last_return_of_each_firing() -> None:
    """nebula's XYZIRCAEDT in dual-return mode: two points per channel and time_stamp, a
    return_type field (3 strongest, 1 last); the last (farther) return of each is kept."""
    dtype = np.dtype({"names": ["x", "y", "z", "channel", "return_type", "time_stamp"],
                      "formats": ["<f4", "<f4", "<f4", "<u2", "<u1", "<u4"],
                      "offsets": [0, 4, 8, 12, 14, 16], "itemsize": 20})  # fmt: skip
    rows = np.zeros(6, dtype=dtype)
    rows["x"] = [4.0, 9.0, 5.0, 5.0, 3.0, 7.0]  # firing 2: both returns on one wall
    rows["channel"] = [0, 0, 1, 1, 0, 0]
    rows["return_type"] = [3, 1, 3, 1, 3, 1]
    rows["time_stamp"] = [100, 100, 200, 200, 300, 300]
    fields = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("channel", 12, 4),
              ("return_type", 14, 2), ("time_stamp", 16, 6)]  # fmt: skip
    pts, ring, dt, rings = decode_sweep(cloud(fields, rows, 20, 10**18), POINT_CLOUD2)
    assert pts[:, 0].tolist() == [9.0, 5.0, 7.0]
    assert ring.tolist() == [0, 1, 0] and rings == 2
    assert dt == pytest.approx([1e-7, 2e-7, 3e-7])


def test_fields_given_twice_and_ring_ids_that_are_no_ring() -> None:
    """A name given twice with one layout is read once; given twice with two, it is refused
    only when read (a second 'intensity' is not). A uint8 ring of 255 (its type's largest)
    is no ring: its point is left out, and the ring count is that of the others."""
    dtype = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("ring", "u1"), ("i", "<f4")])
    rows = np.zeros(3, dtype=dtype)
    rows["x"], rows["ring"] = [1.0, 2.0, 3.0], [0, 255, 4]
    fields = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("ring", 12, 2), ("intensity", 13, 7)]
    msg = cloud([*fields, ("x", 0, 7), ("intensity", 0, 7)], rows, 17, 0)
    pts, ring, _, rings = decode_sweep(msg, POINT_CLOUD2)
    assert pts[:, 0].tolist() == [1.0, 3.0] and ring.tolist() == [0, 4] and rings == 5
    msg = cloud([*fields, ("ring", 4, 7)], rows, 17, 0)
    with pytest.raises(ValueError, match=r"^PointCloud2 field 'ring' given twice \(uint8 at off"):
        decode_sweep(msg, POINT_CLOUD2)
