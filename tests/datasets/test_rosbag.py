"""Bags written with rosbags from a known scene and motion, read back and checked to 1 mm."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from bag_factory import (
    SCANNERS,
    STATIC_TF,
    T0_NS,
    T_BASE,
    T_FP_BL,
    Sensor,
    Truth,
    distance_to_room,
    pose,
    true_pose,
    write_bag,
)
from scipy.spatial import cKDTree

from planodom.datasets import load_dataset
from planodom.datasets.bag_options import BagOptions
from planodom.datasets.rosbag import convert_bag, open_bag
from planodom.errors import DatasetError, OutputError
from planodom.geometry import invert_transform


def check_against_truth(
    ds, scans, truth: Truth, ring_topics: dict[int, str], epochs: list[int] | None = None
) -> None:
    """Every point lies on the room at its true pose, and equals its true hit, within 1 mm."""
    # the true hits of each topic's sweeps, in the base frame at their own time
    true_times, true_base = {}, {}
    for topic in set(ring_topics.values()):
        times = np.concatenate(truth.times[topic])
        T_bw = invert_transform(true_pose(times))
        hits = np.concatenate(truth.world[topic])
        true_times[topic] = times
        true_base[topic] = cKDTree(np.einsum("nij,nj->ni", T_bw[:, :3, :3], hits) + T_bw[:, :3, 3])
    total = 0
    for k, scan in zip(epochs or range(len(scans)), scans, strict=True):
        assert scan.t is not None and scan.ring is not None
        abs_t = ds.times[k] + scan.t
        world = true_pose(abs_t) @ np.append(scan.points, np.ones((len(scan), 1)), 1)[..., None]
        assert distance_to_room(world[:, :3, 0]).max() < 1e-3
        for topic in set(ring_topics.values()):
            sel = np.isin(scan.ring, [r for r, t in ring_topics.items() if t == topic])
            if not sel.any():
                continue
            d, j = true_base[topic].query(scan.points[sel])
            assert d.max() < 1e-3
            assert np.abs(true_times[topic][j] - abs_t[sel]).max() < 1e-6
        assert set(np.unique(scan.ring).tolist()) <= set(ring_topics)
        total += len(scan)
    if epochs is None:
        expected = sum(len(x) for topic in set(ring_topics.values()) for x in truth.times[topic])
        assert total == expected


@pytest.fixture()
def ros1_bag(tmp_path: Path) -> tuple[Path, Truth]:
    path = tmp_path / "rig.bag"
    truth = write_bag(path, 1, SCANNERS, STATIC_TF, T_BASE)
    return path, truth


def test_ros1_laser_scans_land_on_the_truth(ros1_bag: tuple[Path, Truth]) -> None:
    path, truth = ros1_bag
    with open_bag(path, BagOptions(gt_topic="/odom")) as ds:
        assert len(ds) == 12
        scans = list(ds)  # the streaming pass
        for scan in scans:
            assert sorted(set(scan.ring.tolist())) == [0, 1, 2]
        check_against_truth(ds, scans, truth, {0: "/scan_front", 1: "/scan_left", 2: "/scan_rear"})
        # reference times: the sweep stamp nearest each window's centre, in seconds
        # the windows sit between the 0.066 s sweeps and the next 0 s ones: centre 0.033 s
        assert np.allclose(ds.times - T0_NS / 1e9, 0.033 + 0.1 * np.arange(12), atol=1e-6)
        assert ds.times[0] > 1.6e9  # the bag's own clock
        err = np.abs(ds.gt_poses - true_pose(ds.times)).max()
        assert err < 1e-5
        names = ["laser_front", "laser_left", "laser_rear"]
        assert np.allclose(ds.rig.sensor_origins, [T_BASE[n][:3, 3] for n in names], atol=1e-9)
        for T, name in zip(ds.rig.extrinsics, names, strict=True):
            assert np.allclose(T, T_BASE[name], atol=1e-9)
        assert ds.rig.epoch_rate_hz == 10.0


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_ros2_scans_and_lidar(tmp_path: Path, storage: str) -> None:
    sensors = [*SCANNERS[:2], Sensor("/velodyne_points", "lidar", 50_000_000, "velodyne")]
    truth = write_bag(tmp_path / "bag", 2, sensors, STATIC_TF, T_BASE, storage=storage)
    with open_bag(tmp_path / "bag", BagOptions(gt_topic="/odom")) as ds:
        # topics sorted by name: /scan_front, /scan_left, /velodyne_points
        assert [t.name for t in ds.topics] == ["/scan_front", "/scan_left", "/velodyne_points"]
        scans = [ds[k] for k in range(len(ds))]  # random access path
        rings = {0: "/scan_front", 1: "/scan_left"} | {r: "/velodyne_points" for r in range(2, 18)}
        check_against_truth(ds, scans, truth, rings)
        assert ds.rig.sensor_origins.shape == (18, 3)
        assert np.allclose(ds.rig.sensor_origins[2:], T_BASE["lidar"][:3, 3])
        assert np.abs(ds.gt_poses - true_pose(ds.times)).max() < 1e-5
        # the lidar's points of one ring come in scan (time) order
        lidar = scans[3].ring == 7
        assert np.all(np.diff(scans[3].t[lidar]) >= 0)


def test_organised_cloud_with_ns_time_and_tf_pair_reference(tmp_path: Path) -> None:
    sensors = [Sensor("/os/points", "lidar", 0, "ouster")]
    truth = write_bag(tmp_path / "bag", 2, sensors, STATIC_TF, T_BASE, odom=False, tf_odom=True)
    with open_bag(tmp_path / "bag", BagOptions(gt_topic="tf:odom:base_link")) as ds:
        scans = list(ds)
        check_against_truth(ds, scans, truth, {r: "/os/points" for r in range(16)})
        assert np.abs(ds.gt_poses - true_pose(ds.times)).max() < 1e-5
        # odom -> base_link moves: never used as an extrinsic
        assert ("odom", "base_link") in ds._index.tf.moving


def test_chosen_topics_set_the_ring_order(ros1_bag: tuple[Path, Truth]) -> None:
    path, truth = ros1_bag
    with open_bag(path, BagOptions(topics=["/scan_rear", "/scan_front"])) as ds:
        assert ds.gt_poses is None
        assert np.allclose(ds.rig.sensor_origins[0], T_BASE["laser_rear"][:3, 3])
        rings = {0: "/scan_rear", 1: "/scan_front"}
        # phases 0 (front) and 66 ms (rear): windows start at 33 ms, so epoch 0 holds only
        # the front sweep at 0 ms and the others a rear then a front sweep
        assert np.unique(ds[0].ring).tolist() == [1]
        check_against_truth(ds, [ds[0], ds[-1]], truth, rings, [0, len(ds) - 1])


def test_another_base_frame(ros1_bag: tuple[Path, Truth]) -> None:
    # base_footprint is 0.1 m below base_link: the extrinsics and the reference (whose child
    # frame is base_link) move with it
    with open_bag(ros1_bag[0], BagOptions(base_frame="base_footprint", gt_topic="/odom")) as ds:
        expected = true_pose(ds.times) @ invert_transform(T_FP_BL)
        assert np.abs(ds.gt_poses - expected).max() < 1e-5
        assert np.allclose(ds.rig.extrinsics[1], T_FP_BL @ T_BASE["laser_left"], atol=1e-9)
        scan = ds[4]
        shifted = scan.points - T_FP_BL[:3, 3]  # back in base_link
        world = (
            true_pose(ds.times[4] + scan.t)
            @ np.append(shifted, np.ones((len(scan), 1)), 1)[..., None]
        )
        assert distance_to_room(world[:, :3, 0]).max() < 1e-3


def test_convert_bag_writes_a_dataset(ros1_bag: tuple[Path, Truth], tmp_path: Path) -> None:
    path, truth = ros1_bag
    summary = convert_bag(path, tmp_path / "ds", BagOptions(gt_topic="/odom"))
    assert summary.epochs == 12 and summary.rings == 3
    assert summary.points == sum(len(x) for v in truth.times.values() for x in v)
    ds = load_dataset(tmp_path / "ds")
    assert len(ds) == 12
    assert ds.times[0] == pytest.approx(T0_NS / 1e9, abs=0.1)  # the bag's clock in poses.tum
    assert np.abs(ds.gt_poses - true_pose(ds.times)).max() < 1e-5
    rings = {0: "/scan_front", 1: "/scan_left", 2: "/scan_rear"}
    check_against_truth(ds, list(ds), truth, rings)
    assert np.allclose(ds.rig.sensor_origins[2], T_BASE["laser_rear"][:3, 3])


def test_convert_refuses_to_write_into_a_ros2_bag_folder(tmp_path: Path) -> None:
    """``convert BAG BAG/out`` (or ``BAG/data.db3 BAG/out``) wrote the dataset into the
    bag's own folder; ``run`` refused the same, as the README says."""
    write_bag(tmp_path / "bag", 2, SCANNERS[:1], STATIC_TF, T_BASE, duration_s=0.3)
    before = sorted(p.name for p in (tmp_path / "bag").iterdir())
    (data,) = [p for p in (tmp_path / "bag").iterdir() if p.suffix == ".db3"]
    for given in (tmp_path / "bag", data):
        with pytest.raises(OutputError, match=r"bag/out: the output folder lies inside the input"):
            convert_bag(given, tmp_path / "bag" / "out")
    assert sorted(p.name for p in (tmp_path / "bag").iterdir()) == before
    assert convert_bag(data, tmp_path / "ds").epochs == 3  # beside it: fine


def test_convert_without_reference_keeps_the_bag_times(ros1_bag, tmp_path: Path) -> None:
    path, truth = ros1_bag
    convert_bag(path, tmp_path / "ds", BagOptions(epoch_rate=5.0))
    ds = load_dataset(tmp_path / "ds")
    # sweeps at 0, 33, 66 ms + 100 k ms; 200 ms windows start mid of the first largest phase
    # gap (66..100 ms): [-117, 83), [83, 283), ..., [1083, 1283) ms -> 7 epochs
    assert len(ds) == 7
    assert ds.gt_poses is None
    assert (tmp_path / "ds" / "times.txt").is_file() and "bag_epoch_times" not in ds.rig.extra
    bag_times = ds.times  # from times.txt: the bag's own clock
    stamps = np.array(sorted(s for v in truth.stamps.values() for s in v)) / 1e9
    assert np.abs(bag_times[:, None] - stamps[None]).min(axis=1).max() < 1e-6
    assert all(len(set(s.ring.tolist())) == 3 for s in ds)


# ------------------------------------------------------------------ one-line errors


def one_line(exc: pytest.ExceptionInfo[DatasetError]) -> str:
    message = str(exc.value)
    assert "\n" not in message
    return message


def test_missing_tf_names_frame_and_topic(tmp_path: Path) -> None:
    static = [e for e in STATIC_TF if e[1] != "laser_left"]
    write_bag(tmp_path / "a.bag", 1, SCANNERS, static, T_BASE)
    with pytest.raises(DatasetError) as exc:
        open_bag(tmp_path / "a.bag")
    message = one_line(exc)
    assert "'laser_left'" in message and "/scan_left" in message and "base_link" in message


def test_unknown_base_frame(ros1_bag: tuple[Path, Truth]) -> None:
    with pytest.raises(DatasetError) as exc:
        open_bag(ros1_bag[0], BagOptions(base_frame="chassis"))
    assert "'chassis'" in one_line(exc)


def test_bag_without_scan_topics(tmp_path: Path) -> None:
    write_bag(tmp_path / "b", 2, [], STATIC_TF, T_BASE)
    with pytest.raises(DatasetError) as exc:
        open_bag(tmp_path / "b")
    message = one_line(exc)
    assert "no sensor_msgs/LaserScan" in message and "/odom (nav_msgs/msg/Odometry)" in message
    assert "decoded to PointCloud2" in message  # what a bag of raw lidar packets needs


@pytest.mark.parametrize("topic", ["/scan_top", "/odom"])
def test_unknown_or_wrong_topic(ros1_bag: tuple[Path, Truth], topic: str) -> None:
    with pytest.raises(DatasetError) as exc:
        open_bag(ros1_bag[0], BagOptions(topics=["/scan_front", topic]))
    assert f"'{topic}'" in one_line(exc)


def test_unknown_gt_topic(ros1_bag: tuple[Path, Truth]) -> None:
    with pytest.raises(DatasetError) as exc:
        open_bag(ros1_bag[0], BagOptions(gt_topic="/ground_truth"))
    assert "'/ground_truth'" in one_line(exc) and "/odom" in str(exc.value)
    with pytest.raises(DatasetError) as exc:
        open_bag(ros1_bag[0], BagOptions(gt_topic="tf:map:base_link"))
    assert "'map' -> 'base_link'" in one_line(exc)


def truncate(file: Path, keep: float) -> None:
    data = file.read_bytes()
    file.write_bytes(data[: int(len(data) * keep)])


@pytest.mark.parametrize("keep", [0.5, 0.01])
def test_truncated_ros1_bag(ros1_bag: tuple[Path, Truth], keep: float) -> None:
    path = ros1_bag[0]
    truncate(path, keep)
    with pytest.raises(DatasetError) as exc:
        ds = open_bag(path)
        list(ds)
    assert str(path) in one_line(exc)


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_truncated_ros2_bag(tmp_path: Path, storage: str) -> None:
    write_bag(tmp_path / "bag", 2, SCANNERS, STATIC_TF, T_BASE, storage=storage)
    (data,) = [f for f in (tmp_path / "bag").iterdir() if f.suffix in (".db3", ".mcap")]
    truncate(data, 0.5)
    with pytest.raises(DatasetError) as exc:
        ds = open_bag(tmp_path / "bag")
        list(ds)
    assert str(tmp_path / "bag") in one_line(exc)


def test_not_a_bag(tmp_path: Path) -> None:
    with pytest.raises(DatasetError) as exc:
        open_bag(tmp_path / "missing.bag")
    assert "does not exist" in one_line(exc)
    (tmp_path / "x").mkdir()
    with pytest.raises(DatasetError) as exc:
        open_bag(tmp_path / "x")
    assert "not a bag" in one_line(exc)


@pytest.mark.slow
def test_odometry_on_a_lidar_bag(tmp_path: Path) -> None:
    """End to end: the paper's odometry on a converted lidar bag recovers the motion."""
    from planodom.geometry import pose5_from_transform
    from planodom.metrics import relative_motions
    from planodom.odometry.streaming import run_odometry

    sensors = [Sensor("/velodyne_points", "lidar", 0, "velodyne")]
    write_bag(tmp_path / "bag", 2, sensors, STATIC_TF, T_BASE, duration_s=0.6)
    with open_bag(tmp_path / "bag", BagOptions(gt_topic="/odom")) as ds:
        run = run_odometry(ds, rig=ds.rig)
        assert run.statuses[1:] == ["ok"] * (len(ds) - 1)
        est = relative_motions(np.asarray(run.poses))
        gt = relative_motions(ds.gt_poses)
        errors = np.abs([pose5_from_transform(a) - pose5_from_transform(b) for a, b in
                         zip(est, gt, strict=True)])  # fmt: skip
        assert errors[:, :3].max() < np.deg2rad(0.1)  # roll, pitch, yaw
        assert errors[:, 3:].max() < 0.01  # x, y (m)


def test_single_lidar_bag_without_tf_reads_in_the_sensor_frame(tmp_path: Path) -> None:
    """A bag of one lidar and no tf (common from a bare driver): the error names the way out,
    and with the sensor's frame as base frame its points are the sensor's own."""
    lidar = [Sensor("/velodyne_points", "lidar", 0, "velodyne")]
    write_bag(tmp_path / "tf", 2, lidar, STATIC_TF, T_BASE, odom=False)
    write_bag(tmp_path / "notf", 2, lidar, [], T_BASE, odom=False)
    with pytest.raises(DatasetError) as exc:
        open_bag(tmp_path / "notf")
    message = one_line(exc)
    assert "'base_link' is in no transform of the bag" in message
    assert "--base-frame" in message and "'lidar'" in message
    with (
        open_bag(tmp_path / "tf") as with_tf,
        open_bag(tmp_path / "notf", BagOptions(base_frame="lidar")) as bare,
    ):
        assert len(bare) == len(with_tf) > 0
        for k in range(len(bare)):
            own, base = bare[k], with_tf[k]
            in_base = own.points @ T_BASE["lidar"][:3, :3].T + T_BASE["lidar"][:3, 3]
            assert np.abs(in_base - base.points).max() < 1e-9
            assert np.array_equal(own.t, base.t) and np.array_equal(own.ring, base.ring)


def test_time_field_none_puts_every_point_at_its_sweep_stamp(tmp_path: Path) -> None:
    lidar = [Sensor("/velodyne_points", "lidar", 0, "velodyne")]
    write_bag(tmp_path / "b", 2, lidar, STATIC_TF, T_BASE, odom=False)
    with (
        open_bag(tmp_path / "b") as timed,
        open_bag(tmp_path / "b", BagOptions(time_field="none")) as flat,
    ):
        for k in range(len(flat)):
            assert np.array_equal(flat[k].points, timed[k].points)
            assert np.ptp(timed[k].t) > 0.05 and np.ptp(flat[k].t) == 0.0
    with pytest.raises(DatasetError, match="time field must be auto, none or a field name"):
        BagOptions(time_field=" ")


@pytest.mark.parametrize(
    "ros, layout, unit", [(1, "ouster_us", "microseconds"), (2, "velodyne_ms", "milliseconds")]
)
def test_time_offsets_in_another_unit_are_read_by_the_sweep_period(
    tmp_path: Path, ros: int, layout: str, unit: str
) -> None:
    """Integer microseconds were read as nanoseconds (a 0.1 s sweep taken as 0.1 ms, so
    deskewed as one instant, without a word) and float milliseconds refused: only one
    reading makes a sweep span the 0.1 s between its messages."""
    path = tmp_path / ("b.bag" if ros == 1 else "b")
    truth = write_bag(path, ros, [Sensor("/points", "lidar", 0, layout)], STATIC_TF, T_BASE)
    with open_bag(path, BagOptions(gt_topic="/odom")) as ds:
        check_against_truth(ds, list(ds), truth, {r: "/points" for r in range(16)})
        assert len(ds.notes) == 1
        assert f"topic '/points': time field '{'t' if ros == 1 else 'time'}'" in ds.notes[0]
        assert f"read as {unit}" in ds.notes[0]


def test_documented_units_and_one_cloud_topic_give_no_notes(tmp_path: Path) -> None:
    sensors = [Sensor("/os", "lidar", 0, "ouster"), *SCANNERS[:2]]
    write_bag(tmp_path / "b", 2, sensors, STATIC_TF, T_BASE, odom=False)
    with open_bag(tmp_path / "b") as ds:
        assert ds.notes == []


def test_several_cloud_topics_read_are_said(tmp_path: Path) -> None:
    """Every cloud topic is merged into the epochs; a raw and a filtered topic of one lidar
    were merged without a word (the points twice, in two frames of time)."""
    sensors = [Sensor("/points", "lidar", 0, "velodyne"), Sensor("/filtered", "lidar", 0, "ouster")]
    write_bag(tmp_path / "b", 2, sensors, STATIC_TF, T_BASE, odom=False)
    with open_bag(tmp_path / "b") as ds:
        assert len(ds.notes) == 1
        assert "2 point-cloud topics read and merged" in ds.notes[0]
        assert "'/filtered' (lidar, 12 sweeps), '/points' (lidar, 12 sweeps)" in ds.notes[0]
    with open_bag(tmp_path / "b", BagOptions(topics=("/points", "/filtered"))) as ds:
        assert ds.notes == []  # chosen


def test_unstamped_messages_and_a_topic_without_points_are_noted(tmp_path: Path) -> None:
    """Messages stamped 0 took their record time without a word; a cloud topic that never
    held a point made every scan ringless without a word (its rings: none, not unknown)."""
    from dataclasses import replace

    from bag_factory import BagWriter, lidar_cloud

    truth = Truth(T_base_sensor=T_BASE)
    with BagWriter(tmp_path / "b.bag", 1) as bw:
        tf = [bw.transform_stamped(T0_NS, p, c, T) for p, c, T in STATIC_TF]
        bw.write("/tf_static", bw.tf(tf), T0_NS)
        for k in range(5):
            stamp = T0_NS + k * 100_000_000
            msg = lidar_cloud(bw, truth, "/points", "lidar", stamp)
            off = replace(msg, header=bw.header(stamp, "lidar"), width=0, row_step=0,
                          data=np.zeros(0, np.uint8))  # fmt: skip
            if k < 2:
                msg.header.stamp.sec, msg.header.stamp.nanosec = 0, 0
            bw.write("/points", msg, stamp + 2_000_000)
            bw.write("/off", off, stamp + 3_000_000)
    with open_bag(tmp_path / "b.bag", BagOptions(topics=("/points", "/off"))) as ds:
        assert len(ds.notes) == 2
        assert ds.notes[0].startswith("topic '/points': 2 of 5 messages have no header stamp")
        assert ds.notes[1].startswith("topic '/off': none of its 5 messages holds a point")
        assert ds.rig.sensor_origins.shape == (16, 3)
        with open_bag(tmp_path / "b.bag", BagOptions(topics=("/points",))) as alone:
            assert len(alone.notes) == 1
            for k in range(len(ds)):
                np.testing.assert_array_equal(ds[k].ring, alone[k].ring)
                np.testing.assert_array_equal(ds[k].points, alone[k].points)


def test_scans_on_another_clock_than_the_reference_name_both_spans(tmp_path: Path) -> None:
    """A driver stamping with the sensor's clock (seconds since boot): the error gave the
    reference's span only, not the epochs'."""
    from bag_factory import BagWriter, lidar_cloud

    truth = Truth(T_base_sensor=T_BASE)
    with BagWriter(tmp_path / "b.bag", 1) as bw:
        tf = [bw.transform_stamped(T0_NS, p, c, T) for p, c, T in STATIC_TF]
        bw.write("/tf_static", bw.tf(tf), T0_NS)
        for k in range(5):
            stamp = T0_NS + k * 100_000_000
            msg = lidar_cloud(bw, truth, "/points", "lidar", stamp)
            msg.header.stamp.sec = 1234  # since boot
            bw.write("/points", msg, stamp + 2_000_000)
            bw.write("/odom", bw.odometry(stamp, true_pose(stamp / 1e9)), stamp)
    with pytest.raises(DatasetError) as exc:
        open_bag(tmp_path / "b.bag", BagOptions(gt_topic="/odom"))
    message = str(exc.value)
    assert "reference poses from 1700000000.000 to 1700000000.400 s" in message
    assert "epochs from 1234.000 to 1234.400 s" in message and "another clock" in message


def bag_path(folder: Path, ros: int, name: str) -> Path:
    return folder / (f"{name}.bag" if ros == 1 else name)


def _cloud_bag(path: Path, ros: int, extra=None, layout="velodyne", sweep=None) -> None:
    """Five 10 Hz sweeps on /points (stamps on the 100 ms grid, ``layout`` of
    :func:`lidar_cloud`) and /odom; ``sweep(k, msg)`` gives the message written for sweep
    ``k`` (None: none), ``extra(bw, k, stamp, msg)`` writes more messages after it."""
    from bag_factory import BagWriter, lidar_cloud, write_rig_and_odometry

    truth = Truth(T_base_sensor=T_BASE)
    with BagWriter(path, ros) as bw:
        write_rig_and_odometry(bw, 7)
        for k in range(5):
            stamp = T0_NS + k * 100_000_000
            msg = lidar_cloud(bw, truth, "/points", "lidar", stamp, layout)
            if sweep is not None and (msg := sweep(k, msg)) is None:
                continue
            bw.write("/points", msg, stamp + 2_000_000)
            if extra is not None:
                extra(bw, k, stamp, msg)


@contextmanager
def _beside_clean(tmp_path: Path, ros: int, name: str, extra) -> Iterator[tuple]:
    """The bag ``name`` (:func:`_cloud_bag` with ``extra``) and the clean one, both read with
    the /odom reference: ``(ds, clean)``."""
    _cloud_bag(bag_path(tmp_path, ros, "clean"), ros)
    _cloud_bag(bag_path(tmp_path, ros, name), ros, extra)
    opts = BagOptions(gt_topic="/odom")
    with (
        open_bag(bag_path(tmp_path, ros, name), opts) as ds,
        open_bag(bag_path(tmp_path, ros, "clean"), opts) as clean,
    ):
        yield ds, clean


def _assert_same_reading(ds, clean) -> None:
    """The same epochs, reference poses and scans as the clean bag's, to the bit."""
    np.testing.assert_array_equal(ds.gt_poses, clean.gt_poses)
    _assert_same_scans(ds, clean)


@pytest.mark.parametrize("ros", [1, 2])
def test_a_topic_without_points_places_no_epoch(tmp_path: Path, ros: int) -> None:
    """A cloud topic that never held a point, stamped 50 ms after the lidar's sweeps, moved
    the epochs' windows and reference times (ATE 1.30 mm instead of 1.08 on a 20-epoch
    probe): it is left out of the epochs, so the bag reads as the one without it."""
    from dataclasses import replace

    def off(bw, k, stamp, msg):
        empty = replace(msg, header=bw.header(stamp + 50_000_000, "lidar"), width=0,
                        row_step=0, data=np.zeros(0, np.uint8))  # fmt: skip
        bw.write("/off", empty, stamp + 52_000_000)

    with _beside_clean(tmp_path, ros, "off", off) as (ds, clean):
        assert [t.name for t in ds.topics] == ["/off", "/points"]
        _assert_same_reading(ds, clean)
        assert ds.notes == [  # and no two cloud topics merged: /off adds no point
            "topic '/off': none of its 5 messages holds a point (the sensor off, or "
            "everything filtered out?); left out of the epochs"
        ]


@pytest.mark.parametrize("ros", [1, 2])
def test_a_message_recorded_twice_is_read_once(tmp_path: Path, ros: int) -> None:
    """A sweep recorded twice (merged or overlapping recordings; in ROS 1 its header's
    ``seq`` may differ) went into its epoch twice without a word: it is read once and
    noted. A message of the same stamp and other content is another sweep: kept, and (its
    epoch holding two messages of the topic where the others hold one) noted."""
    from dataclasses import replace

    def twice(bw, k, stamp, msg):
        if k in (1, 3):
            if ros == 1:
                msg = replace(msg, header=replace(msg.header, seq=k + 100))
            bw.write("/points", msg, stamp + 60_000_000)

    def other(bw, k, stamp, msg):
        if k == 2:  # its first half, say a driver's packet
            half = replace(msg, width=msg.width // 2, row_step=msg.row_step // 2,
                           data=msg.data[: len(msg.data) // 2])  # fmt: skip
            bw.write("/points", half, stamp + 3_000_000)

    _cloud_bag(bag_path(tmp_path, ros, "clean"), ros)
    _cloud_bag(bag_path(tmp_path, ros, "twice"), ros, twice)
    _cloud_bag(bag_path(tmp_path, ros, "other"), ros, other)
    opts = BagOptions(gt_topic="/odom")
    with (
        open_bag(bag_path(tmp_path, ros, "twice"), opts) as ds,
        open_bag(bag_path(tmp_path, ros, "clean"), opts) as clean,
    ):
        _assert_same_reading(ds, clean)
        for k in (1, 3):  # read on their own too
            np.testing.assert_array_equal(ds[k].points, clean[k].points)
        assert ds.notes == [
            "topic '/points': 2 of 7 messages recorded twice (the stamp and content of an "
            "earlier one: merged or overlapping recordings?), read once"
        ]
    with (
        open_bag(bag_path(tmp_path, ros, "other"), opts) as ds,
        open_bag(bag_path(tmp_path, ros, "clean"), opts) as clean,
    ):
        (note,) = ds.notes
        t2 = f"{ds.times[2]:.3f}"
        assert note.startswith(
            f"topic '/points': 1 epoch(s) hold more of its messages than the 1 most hold "
            f"(first: epoch 2, t = {t2} s, stamps {t2}000000, {t2}000000 s: stamped alike"
        )
        np.testing.assert_array_equal(ds.times, clean.times)
        whole, with_half = clean[2], ds[2]
        assert 1.4 * len(whole) < len(with_half) < 1.6 * len(whole)
        assert [len(ds[k]) for k in (0, 1, 3, 4)] == [len(clean[k]) for k in (0, 1, 3, 4)]


def _without_points(msg):
    from dataclasses import replace

    return replace(msg, width=0, row_step=0, data=np.zeros(0, np.uint8))


@pytest.mark.parametrize("ros", [1, 2])
def test_messages_without_points_place_no_epoch(tmp_path: Path, ros: int) -> None:
    """Sweeps without a point (a dropout) inside a topic with points placed epochs of their
    own, without points, which the odometry bridged: they are left out and noted, so the
    bag reads as the one without those messages."""

    def gap(k, msg):
        return _without_points(msg) if k == 2 else msg

    _cloud_bag(bag_path(tmp_path, ros, "clean"), ros, sweep=lambda k, m: None if k == 2 else m)
    _cloud_bag(bag_path(tmp_path, ros, "gap"), ros, sweep=gap)
    opts = BagOptions(gt_topic="/odom")
    with (
        open_bag(bag_path(tmp_path, ros, "gap"), opts) as ds,
        open_bag(bag_path(tmp_path, ros, "clean"), opts) as clean,
    ):
        assert len(ds) == 4
        _assert_same_reading(ds, clean)
        assert ds.notes == [
            "topic '/points': 1 of 5 messages hold no point (dropouts, or everything filtered "
            "out?); left out of the epochs"
        ]


def test_an_empty_laser_scan_keeps_its_place_in_a_2d_rig(tmp_path: Path) -> None:
    """A LaserScan without a return is normal in a 2D rig (open space): its epoch keeps the
    other scanners' points and its stamp, which stays the epoch's reference time."""
    from dataclasses import replace

    from bag_factory import BagWriter, laser_scan

    def rig(path: Path, blind: bool) -> None:
        truth = Truth(T_base_sensor=T_BASE)
        with BagWriter(path, 1) as bw:
            tf = [bw.transform_stamped(T0_NS, p, c, T) for p, c, T in STATIC_TF]
            bw.write("/tf_static", bw.tf(tf), T0_NS)
            for k in range(4):
                for s in SCANNERS:
                    stamp = T0_NS + k * 100_000_000 + s.phase_ns
                    msg = laser_scan(bw, truth, s.topic, s.frame, stamp)
                    if blind and k == 2 and s.topic == "/scan_left":
                        msg = replace(msg, ranges=np.full_like(msg.ranges, np.inf))
                    bw.write(s.topic, msg, stamp + 2_000_000)

    rig(tmp_path / "clean.bag", False)
    rig(tmp_path / "blind.bag", True)
    with open_bag(tmp_path / "blind.bag") as ds, open_bag(tmp_path / "clean.bag") as clean:
        np.testing.assert_array_equal(ds.times, clean.times)  # epoch 2's still /scan_left's
        assert ds.notes == []
        scans = list(ds)
        assert sorted(set(scans[2].ring.tolist())) == [0, 2]
        assert sorted(set(scans[1].ring.tolist())) == [0, 1, 2]


def _sliver(msg):
    """The first two columns (0.4 ms) of an organised ``ouster`` sweep: a cloud cropped to
    a sliver of the turn, whose span lies nearer the 0.1 s period read as microseconds."""
    from dataclasses import replace

    rows = np.asarray(msg.data, np.uint8).reshape(msg.height, msg.row_step)
    data = np.ascontiguousarray(rows[:, : 2 * msg.point_step]).ravel()
    return replace(msg, width=2, row_step=2 * msg.point_step, data=data)


@pytest.mark.parametrize("ros", [1, 2])
def test_a_sweep_recorded_twice_votes_once_for_the_time_unit(tmp_path: Path, ros: int) -> None:
    """Three whole sweeps vote nanoseconds, two slivers microseconds: nanoseconds, not
    clear-cut. Each sliver recorded twice voted twice, so microseconds won 4 to 3 and the
    whole sweeps' 0.1 s read as 100 s were refused: each sweep votes once."""
    from dataclasses import replace

    def twice(bw, k, stamp, msg):
        if k in (1, 3):
            if ros == 1:
                msg = replace(msg, header=replace(msg.header, seq=k + 100))
            bw.write("/points", msg, stamp + 60_000_000)

    def slivers(k, msg):
        return _sliver(msg) if k in (1, 3) else msg

    _cloud_bag(bag_path(tmp_path, ros, "clean"), ros, layout="ouster", sweep=slivers)
    _cloud_bag(bag_path(tmp_path, ros, "twice"), ros, twice, "ouster", slivers)
    opts = BagOptions(gt_topic="/odom")
    with (
        open_bag(bag_path(tmp_path, ros, "twice"), opts) as ds,
        open_bag(bag_path(tmp_path, ros, "clean"), opts) as clean,
    ):
        assert clean.notes == [
            "topic '/points': time field 't' (uint32) read as nanoseconds, but not clear-cut: "
            "2 of 5 sweeps span nearer the period as microseconds; as microseconds a sweep "
            "would span 99.6 s of the 100 ms between messages, as nanoseconds 99.6 ms "
            "(median); --time-field none ignores the times"
        ]
        _assert_same_reading(ds, clean)
        assert ds.notes == [
            clean.notes[0],
            "topic '/points': 2 of 7 messages recorded twice (the stamp and content of an "
            "earlier one: merged or overlapping recordings?), read once",
        ]


def _recorded_twice(ros: int, bw, msg, stamp: int) -> None:
    """``msg`` written again 60 ms later (ROS 1: another header ``seq``)."""
    from dataclasses import replace

    if ros == 1:
        msg = replace(msg, header=replace(msg.header, seq=77))
    bw.write("/points", msg, stamp + 60_000_000)


@pytest.mark.parametrize("ros", [1, 2])
def test_rig_counts_the_sweeps_read(tmp_path: Path, ros: int) -> None:
    """``rig.extra``'s per-topic ``sweeps`` and the "merged" note counted every message,
    the empty one and the one recorded twice too (6 for /points): they count the sweeps
    read into the epochs (4), and ``left_out`` the others."""
    from dataclasses import replace

    def more(bw, k, stamp, msg):
        if k == 1:
            _recorded_twice(ros, bw, msg, stamp)
        if msg.width:
            other = replace(msg, header=bw.header(stamp + 50_000_000, "lidar"))
            bw.write("/points_b", other, stamp + 52_000_000)

    def gap(k, msg):
        return _without_points(msg) if k == 2 else msg

    _cloud_bag(bag_path(tmp_path, ros, "b"), ros, more, sweep=gap)
    with open_bag(bag_path(tmp_path, ros, "b")) as ds:
        points, points_b = ds.rig.extra["topics"]
        assert (points["topic"], points["sweeps"], points["left_out"]) == ("/points", 4, 2)
        assert (points_b["topic"], points_b["sweeps"]) == ("/points_b", 4)
        assert "left_out" not in points_b
        assert ds.notes[-1].startswith(
            "2 point-cloud topics read and merged into each epoch: '/points' (lidar, 4 "
            "sweeps), '/points_b' (lidar, 4 sweeps)"
        )


@pytest.mark.parametrize("ros", [1, 2])
def test_a_topic_without_points_needs_no_transform(tmp_path: Path, ros: int) -> None:
    """A cloud topic that never held a point (a sensor switched off) on a frame the tf tree
    does not know refused the bag, though it adds nothing to the epochs: it needs no
    transform now, and gives the rig no extrinsic."""
    from dataclasses import replace

    def off(bw, k, stamp, msg):
        empty = replace(_without_points(msg), header=bw.header(stamp + 50_000_000, "radar"))
        bw.write("/off", empty, stamp + 52_000_000)

    with _beside_clean(tmp_path, ros, "off", off) as (ds, clean):
        _assert_same_reading(ds, clean)
        assert len(ds.rig.extrinsics) == 1
        np.testing.assert_array_equal(ds.rig.extrinsics[0], clean.rig.extrinsics[0])
        np.testing.assert_array_equal(ds.rig.sensor_origins, clean.rig.sensor_origins)
        off_topic = ds.rig.extra["topics"][0]
        assert (off_topic["frame"], off_topic["sweeps"], off_topic["left_out"]) == ("radar", 0, 5)
    with pytest.raises(DatasetError, match="topic '/off': no transform from frame 'radar'"):
        open_bag(bag_path(tmp_path, ros, "off"), BagOptions(topics=("/off",)))


@pytest.mark.parametrize("ros", [1, 2])
def test_reference_poses_invalid_or_given_twice(tmp_path: Path, ros: int) -> None:
    """Reference poses between the clean ones: one with a NaN position (read as NaN into the
    epochs' reference), one with a zero quaternion (refused the bag), one recorded twice
    and two of one stamp with different poses (silently the last). The invalid ones are
    left out and the others noted; the epochs' reference poses are the clean bag's."""
    from dataclasses import replace

    def odom(bw, k, stamp, msg):
        at = stamp + 50_000_000
        if k == 1:
            T = true_pose(at / 1e9)
            T[0, 3] = np.nan
            bw.write("/odom", bw.odometry(at, T), at)
        if k == 3:
            good = bw.odometry(at, true_pose(at / 1e9))
            q = bw.T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=0.0)
            zero = replace(good.pose.pose, orientation=q)
            bw.write("/odom", replace(good, pose=replace(good.pose, pose=zero)), at)
        if k == 2:  # the clean bag's pose at this stamp, again
            bw.write("/odom", bw.odometry(stamp, true_pose(stamp / 1e9)), stamp + 1)
        if k == 4:  # after the last epoch, another pose at the last pose's stamp
            later = stamp + 200_000_000
            bw.write("/odom", bw.odometry(later, pose(0, 0, 0, (5.0, 0.0, 0.0))), later)

    with _beside_clean(tmp_path, ros, "gt", odom) as (ds, clean):
        np.testing.assert_array_equal(ds.times, clean.times)
        np.testing.assert_array_equal(ds.gt_poses, clean.gt_poses)
        assert ds.notes[0].startswith(
            "gt '/odom': 2 of 12 poses invalid (the first: invalid translation [nan, "
        )
        assert ds.notes[0].endswith("]), left out: the reference is interpolated across them")
        assert ds.notes[1:] == [
            "gt '/odom': 1 of 12 poses recorded twice (the stamp and pose of an earlier one), "
            "read once",
            "gt '/odom': 1 of 12 poses repeat an earlier stamp with another pose (two "
            "publishers on one topic?); the last of each stamp is used",
        ]


def test_a_single_laser_scan_without_a_return_places_no_epoch(tmp_path: Path) -> None:
    """A bag of one 2D scanner: a scan without any return placed an epoch without points,
    bridged by the odometry. No other scanner fills it: it is left out as a cloud's empty
    message is, and noted; the bag reads as the one without that message."""
    from dataclasses import replace

    from bag_factory import BagWriter, laser_scan

    def scanner(path: Path, blind: bool | None) -> None:
        truth = Truth(T_base_sensor=T_BASE)
        with BagWriter(path, 1) as bw:
            tf = [bw.transform_stamped(T0_NS, p, c, T) for p, c, T in STATIC_TF]
            bw.write("/tf_static", bw.tf(tf), T0_NS)
            for k in range(5):
                stamp = T0_NS + k * 100_000_000
                msg = laser_scan(bw, truth, "/scan_front", "laser_front", stamp)
                if k == 2 and blind is None:
                    continue
                if k == 2 and blind:
                    msg = replace(msg, ranges=np.full_like(msg.ranges, np.inf))
                bw.write("/scan_front", msg, stamp + 2_000_000)

    scanner(tmp_path / "clean.bag", None)
    scanner(tmp_path / "blind.bag", True)
    with open_bag(tmp_path / "blind.bag") as ds, open_bag(tmp_path / "clean.bag") as clean:
        assert len(ds) == 4
        np.testing.assert_array_equal(ds.times, clean.times)
        for scan, truth in zip(ds, clean, strict=True):
            np.testing.assert_array_equal(scan.points, truth.points)
            np.testing.assert_array_equal(scan.t, truth.t)
        assert ds.notes == [
            "topic '/scan_front': 1 of 5 scans hold no return (open space, or everything "
            "beyond range_max?); left out of the epochs"
        ]


@pytest.mark.parametrize("ros", [1, 2])
def test_zero_ranges_of_a_laser_scan_with_range_min_0_are_no_returns(
    tmp_path: Path, ros: int
) -> None:
    """Drivers write a beam without an echo as range 0 (and leave range_min 0): each became
    a point at the scanner's origin, a cluster the extraction took for a wall's hit. A
    range of 0 is no return, as inf is: the bag reads as the one with inf there."""
    from dataclasses import replace

    from bag_factory import BagWriter, laser_scan

    def scanner(path: Path, none: float) -> None:
        truth = Truth(T_base_sensor=T_BASE)
        with BagWriter(path, ros) as bw:
            tf = [bw.transform_stamped(T0_NS, p, c, T) for p, c, T in STATIC_TF]
            bw.write("/tf_static", bw.tf(tf), T0_NS)
            for k in range(3):
                stamp = T0_NS + k * 100_000_000
                msg = laser_scan(bw, truth, "/scan_front", "laser_front", stamp)
                ranges = np.where(np.isfinite(msg.ranges), msg.ranges, none).astype(np.float32)
                msg = replace(msg, ranges=ranges, range_min=0.0)
                bw.write("/scan_front", msg, stamp + 2_000_000)

    scanner(bag_path(tmp_path, ros, "zero"), 0.0)
    scanner(bag_path(tmp_path, ros, "inf"), np.inf)
    with open_bag(bag_path(tmp_path, ros, "zero")) as ds:
        with open_bag(bag_path(tmp_path, ros, "inf")) as clean:
            _assert_same_scans(ds, clean)
            assert all(len(scan) == 389 for scan in ds)  # 400 beams, 11 without an echo


@pytest.mark.parametrize("ros", [1, 2])
def test_a_reference_over_part_of_the_run_keeps_every_epoch(tmp_path: Path, ros: int) -> None:
    """A reference that stops half-way (odometry recorded for the first 0.25 s) made ``run``
    read only the epochs it spans (the sixth pass noted it): the rest of the recording was
    lost to the odometry. Every epoch is read, as without a reference, its reference pose
    NaN outside the span; ``convert`` still leaves those out (a pose a scan), and says so."""
    from bag_factory import BagWriter, lidar_cloud

    truth = Truth(T_base_sensor=T_BASE)
    with BagWriter(bag_path(tmp_path, ros, "half"), ros) as bw:
        tf = [bw.transform_stamped(T0_NS, p, c, T) for p, c, T in STATIC_TF]
        bw.write("/tf_static", bw.tf(tf), T0_NS)
        for k in range(5):
            stamp = T0_NS + k * 100_000_000
            bw.write("/points", lidar_cloud(bw, truth, "/points", "lidar", stamp), stamp + 1)
            odom = stamp + 50_000_000
            if k < 2:
                bw.write("/odom", bw.odometry(odom, true_pose(odom / 1e9)), odom)
    span = (
        "gt '/odom' spans 1 of the 5 epochs (reference poses from 1700000000.050 to "
        "1700000000.150 s, epochs from 1700000000.000 to 1700000000.400 s): "
    )
    with (
        open_bag(bag_path(tmp_path, ros, "half"), BagOptions(gt_topic="/odom")) as ds,
        open_bag(bag_path(tmp_path, ros, "half")) as every,
    ):
        assert (len(ds), ds.epochs_without_gt) == (5, 4)
        _assert_same_scans(ds, every)
        assert ds.gt_poses is not None
        np.testing.assert_allclose(
            ds.gt_poses[1], true_pose(ds.times[1]), atol=1e-4
        )  # interpolated
        assert np.isnan(ds.gt_poses[[0, 2, 3, 4]]).all()
        assert ds.notes == [span + "every epoch is read; the metrics are over the epochs it spans"]
    c = convert_bag(bag_path(tmp_path, ros, "half"), tmp_path / "ds", BagOptions(gt_topic="/odom"))
    assert (c.epochs, c.dropped_epochs) == (1, 4)
    assert c.notes == (
        span + "the 4 epochs outside it left out (without --gt-topic every epoch is written)",
    )
    written = load_dataset(tmp_path / "ds")
    np.testing.assert_allclose(written.times, [T0_NS / 1e9 + 0.1])


@pytest.mark.parametrize("ros", [1, 2])
def test_a_gap_in_the_reference_leaves_its_epochs_without_one(tmp_path: Path, ros: int) -> None:
    """Odometry at 200 Hz but for 0.25 s to 0.75 s (a GNSS outage): the five epochs in the gap
    got a pose interpolated along the straight line across it, silently, and the metrics
    compared them. Their reference is NaN now, noted; the metrics pair no epochs across it."""
    from planodom.results import trajectory_metrics

    def odom(bw) -> None:
        for k in range(241):
            stamp = T0_NS - 100_000_000 + k * 5_000_000
            if not T0_NS + 250_000_000 < stamp < T0_NS + 750_000_000:
                bw.write("/odom", bw.odometry(stamp, true_pose(stamp / 1e9)), stamp)

    path = bag_path(tmp_path, ros, "gap")
    sensors = [Sensor("/points", "lidar", 0, "velodyne")]
    write_bag(path, ros, sensors, STATIC_TF, T_BASE, duration_s=1.0, odom=False, extra=odom)
    with open_bag(path, BagOptions(gt_topic="/odom")) as ds, open_bag(path) as every:
        assert (len(ds), ds.epochs_without_gt) == (10, 5)
        _assert_same_scans(ds, every)
        assert ds.gt_poses is not None
        gap = [3, 4, 5, 6, 7]  # epochs at 0.3 ... 0.7 s
        assert np.isnan(ds.gt_poses[gap]).all()
        kept = [0, 1, 2, 8, 9]
        assert np.abs(ds.gt_poses[kept] - true_pose(ds.times[kept])).max() < 1e-5
        assert ds.notes == [
            "gt '/odom' spans 5 of the 10 epochs (reference poses from 1699999999.900 to "
            "1700000001.100 s with a gap from 1700000000.250 to 1700000000.750 s, epochs from "
            "1700000000.000 to 1700000000.900 s): every epoch is read; the metrics are over "
            "the epochs it spans"
        ]
        # an estimate right but for a 1 m jump in the gap: no relative error sees it
        est = true_pose(ds.times)
        est[5:, 0, 3] += 1.0
        m = trajectory_metrics(est, ds.gt_poses)
        assert (m["epochs"], m["evaluated_epochs"]) == (10, 5)
        assert m["rpe_trans_max_m"] == pytest.approx(0.0, abs=1e-5)
    c = convert_bag(path, tmp_path / "ds", BagOptions(gt_topic="/odom"))
    assert (c.epochs, c.dropped_epochs) == (5, 5)


@pytest.mark.parametrize("ros", [1, 2])
def test_a_reference_of_an_unnamed_or_unlinked_frame_is_noted(tmp_path: Path, ros: int) -> None:
    """A PoseStamped reference names no child frame, an Odometry's child frame may be linked
    to the base by no transform: both were read as the base frame's poses without a word
    (the lidar 1.60 m from base_link here). They read the same, and are noted now."""
    stamps = [T0_NS - 100_000_000 + k * 5_000_000 for k in range(241)]

    def pose_stamped(bw, topic: str = "/pose", frame: str = "map") -> None:
        for stamp in stamps:
            t, q = bw.geometry(true_pose(stamp / 1e9))
            point = bw.T["geometry_msgs/msg/Point"](x=t[0], y=t[1], z=t[2])
            msg = bw.T["geometry_msgs/msg/PoseStamped"](
                header=bw.header(stamp, frame),
                pose=bw.T["geometry_msgs/msg/Pose"](position=point, orientation=q),
            )
            bw.write(topic, msg, stamp)

    def pose_in_odom(bw) -> None:  # with the bag's /tf moving base_link in odom
        pose_stamped(bw, "/pose_odom", "odom")

    def odom_of_imu(bw) -> None:
        for stamp in stamps:
            msg = bw.odometry(stamp, true_pose(stamp / 1e9))
            bw.write("/odom_imu", replace(msg, child_frame_id="imu"), stamp)

    sensors = [Sensor("/points", "lidar", 0, "velodyne")]
    notes = {
        "/pose": "gt '/pose': its poses in 'map' name no child frame (a PoseStamped's do not "
        "say which frame they are of): read as the base frame 'base_link''s poses; if they "
        "are another frame's (the lidar's, an IMU's, a GNSS antenna's), the reference is "
        "off by the lever arm between the two (from 'base_link' the scans' frame 'lidar' "
        "1.60 m away): give that frame as --base-frame, or record an Odometry with its "
        "child_frame_id",
        "/odom_imu": "gt '/odom_imu': its poses are of frame 'imu', which no static transform "
        "links to the base frame 'base_link': read as the base frame's poses, off by the "
        "lever arm between the two (give 'imu' as --base-frame, or record the transform in "
        "/tf_static)",
    }
    notes["/pose_odom"] = (
        notes["/pose"]
        .replace("'/pose': its poses in 'map'", "'/pose_odom': its poses in 'odom'")
        .replace(
            "--base-frame,",
            "--base-frame, or a /tf reference of a named frame (tf:odom:base_link),",
        )
    )
    for topic, extra in (
        ("/pose", pose_stamped),
        ("/odom_imu", odom_of_imu),
        ("/pose_odom", pose_in_odom),
    ):
        path = bag_path(tmp_path, ros, topic[1:])
        tf = topic == "/pose_odom"
        write_bag(path, ros, sensors, STATIC_TF, T_BASE, duration_s=1.0, tf_odom=tf, extra=extra)
        with (
            open_bag(path, BagOptions(gt_topic=topic)) as ds,
            open_bag(path, BagOptions(gt_topic="/odom")) as odom,
        ):
            assert ds.gt_poses is not None and odom.gt_poses is not None
            np.testing.assert_allclose(ds.gt_poses, odom.gt_poses, atol=1e-9)
            assert ds.notes == [notes[topic]]
            assert odom.notes == []  # an Odometry of base_link


def _assert_same_scans(ds, other) -> None:
    """The same epoch times and scans, to the bit."""
    np.testing.assert_array_equal(ds.times, other.times)
    for scan, truth in zip(ds, other, strict=True):
        np.testing.assert_array_equal(scan.points, truth.points)
        np.testing.assert_array_equal(scan.ring, truth.ring)
        np.testing.assert_array_equal(scan.t, truth.t)


@pytest.mark.parametrize("ros", [1, 2])
def test_reference_poses_of_two_publishers_are_said(tmp_path: Path, ros: int) -> None:
    """Two publishers on the gt topic (a wheel odometry and a localisation, say: frames
    ``odom`` and ``map``) made one trajectory of two without a word: it is said."""
    from dataclasses import replace

    def second(bw, k, stamp, msg):
        if k == 4:  # after the last epoch: the reading stays the clean bag's
            at = stamp + 250_000_000
            odom = bw.odometry(at, true_pose(at / 1e9))
            bw.write("/odom", replace(odom, header=bw.header(at, "map")), at)

    with _beside_clean(tmp_path, ros, "two", second) as (ds, clean):
        _assert_same_reading(ds, clean)
        assert ds.notes == [
            "gt '/odom': its poses name 2 frame pairs, odom -> base_link (8), map -> "
            "base_link (1) (two publishers on one topic?); they are read as one trajectory"
        ]


def _velodyne_rows(msg) -> np.ndarray:
    """A velodyne-layout cloud's points (:func:`lidar_cloud`) as a writable structured array."""
    dtype = np.dtype({"names": ["x", "intensity", "ring"], "formats": ["<f4", "<f4", "<u2"],
                      "offsets": [0, 12, 16], "itemsize": 22})  # fmt: skip
    return np.frombuffer(bytearray(bytes(msg.data)), dtype=dtype)  # the other bytes kept


def _with_rows(msg, rows: np.ndarray, fields=None):
    from dataclasses import replace

    data = np.frombuffer(rows.tobytes(), np.uint8)
    return replace(msg, data=data, fields=msg.fields if fields is None else fields)


@pytest.mark.parametrize("ros", [1, 2])
def test_a_no_ring_id_leaves_its_points_out_with_a_note(tmp_path: Path, ros: int) -> None:
    """Ten points of one sweep with ring 65535 (uint16's largest, a driver's "no ring") made
    a rig of 65536 rings (sensor origins) without a word. They are left out and noted: the
    bag reads as the one whose ten points are no returns (NaN), with 16 rings."""
    stray = np.arange(110, 120)  # no point among them is a no return (every 53rd)

    def mark(field: str):
        def sweep(k, msg):
            if k != 2:
                return msg
            rows = _velodyne_rows(msg)
            rows[field][stray] = 65535 if field == "ring" else np.nan
            return _with_rows(msg, rows)

        return sweep

    _cloud_bag(bag_path(tmp_path, ros, "nan"), ros, sweep=mark("x"))
    _cloud_bag(bag_path(tmp_path, ros, "stray"), ros, sweep=mark("ring"))
    with (
        open_bag(bag_path(tmp_path, ros, "stray")) as ds,
        open_bag(bag_path(tmp_path, ros, "nan")) as clean,
    ):
        _assert_same_reading(ds, clean)
        assert len(ds.rig.sensor_origins) == 16
        assert clean.notes == []
        assert ds.notes == [
            "topic '/points': 10 points carry their ring field type's largest value (65535 "
            'in a uint16) as ring id, a driver\'s "no ring"?; left out'
        ]


@pytest.mark.parametrize("ros", [1, 2])
@pytest.mark.parametrize("case", ["fraction", "twice"])
def test_a_fractional_ring_or_a_field_given_twice_is_refused_naming_it(
    tmp_path: Path, ros: int, case: str
) -> None:
    """A float ring of 3.5 was truncated to ring 3; of two fields named ``x`` (at offsets 0
    and 12) the first was read. Both silently: each is refused, naming topic and field."""

    def sweep(k, msg):
        rows = _velodyne_rows(msg)
        fields = list(msg.fields)
        if case == "fraction":  # the ring as float32 in the intensity's place, plus 0.5
            rows["intensity"] = rows["ring"] + 0.5
            ring = next(i for i, f in enumerate(fields) if f.name == "ring")
            fields[ring] = type(fields[ring])(name="ring", offset=12, datatype=7, count=1)
        else:
            fields.append(type(fields[0])(name="x", offset=12, datatype=7, count=1))
        return _with_rows(msg, rows, fields)

    _cloud_bag(bag_path(tmp_path, ros, case), ros, sweep=sweep)
    with pytest.raises(DatasetError) as exc:
        open_bag(bag_path(tmp_path, ros, case))
    expected = {
        # 3840 points, every 53rd a no return (73): 3767 points with a ring
        "fraction": "PointCloud2 ring field 'ring' (float32) holds 0.5 at 3767 of 3767 "
        "points, not a whole ring id",
        "twice": "PointCloud2 field 'x' given twice (float32 at offset 0 and float32 at "
        "offset 12): which one holds its values is unknown",
    }[case]
    assert one_line(exc).endswith(f"topic '/points': {expected}")


@pytest.mark.parametrize("ros", [1, 2])
@pytest.mark.parametrize("case", ["float_65535", "ring_200", "int16_negative"])
def test_ring_ids_that_are_no_ring_are_left_out(tmp_path: Path, ros: int, case: str) -> None:
    """Ten points of one sweep whose ring id is no ring of the 16: a float field's 65535.0
    (a float has no type maximum to be the "no ring" by), a stray 200, or -1 in an int16
    field. The first two made a rig of 65 536 and 201 rings without a word, the third
    refused the bag. Each is left out and noted: the bag reads as the one whose ten
    points are no returns (NaN), with 16 rings (:mod:`planodom.datasets.bag_rings`)."""
    stray = np.arange(110, 120)  # no point among them is a no return (every 53rd)

    def sweep(k, msg):
        rows = _velodyne_rows(msg)
        fields = list(msg.fields)
        ring = next(i for i, f in enumerate(fields) if f.name == "ring")
        if case == "float_65535":  # the ring as float32 in the intensity's place
            rows["intensity"] = rows["ring"]
            fields[ring] = type(fields[ring])(name="ring", offset=12, datatype=7, count=1)
            if k == 2:
                rows["intensity"][stray] = 65535.0
        elif case == "int16_negative":  # uint16 65535 read as int16 is -1
            fields[ring] = type(fields[ring])(name="ring", offset=16, datatype=3, count=1)
            if k == 2:
                rows["ring"][stray] = 65535
        elif k == 2:
            rows["ring"][stray] = 200
        return _with_rows(msg, rows, fields)

    def nan(k, msg):
        if k != 2:
            return msg
        rows = _velodyne_rows(msg)
        rows["x"][stray] = np.nan
        return _with_rows(msg, rows)

    _cloud_bag(bag_path(tmp_path, ros, "nan"), ros, sweep=nan)
    _cloud_bag(bag_path(tmp_path, ros, case), ros, sweep=sweep)
    with (
        open_bag(bag_path(tmp_path, ros, case)) as ds,
        open_bag(bag_path(tmp_path, ros, "nan")) as clean,
    ):
        _assert_same_scans(ds, clean)
        assert len(ds.rig.sensor_origins) == 16
        value = {"float_65535": 65535, "ring_200": 200, "int16_negative": -1}[case]
        assert ds.notes == [
            "topic '/points': 10 points carry ring ids that are no ring of its lidar's "
            f"numbering beside its rings 0..15 (1 id: {value}; negative, or apart from the "
            "others by more unused ids than they count); left out"
        ]


@pytest.mark.parametrize("ros", [1, 2])
def test_stamps_going_back_within_a_topic_are_said(tmp_path: Path, ros: int) -> None:
    """Sweep 3 stamped 0.7 s before the first (a sensor clock reset) was read as the first
    epoch without a word, the odometry then stepping back in time. It is noted."""
    from dataclasses import replace

    def reset(k, msg):
        if k != 3:
            return msg
        stamp = T0_NS - 700_000_000
        header = replace(msg.header, stamp=replace(msg.header.stamp, sec=stamp // 10**9,
                                                   nanosec=stamp % 10**9))  # fmt: skip
        return replace(msg, header=header)

    _cloud_bag(bag_path(tmp_path, ros, "back"), ros, sweep=reset)
    with open_bag(bag_path(tmp_path, ros, "back")) as ds:
        assert len(ds) == 5 and ds.times[0] == pytest.approx(T0_NS / 1e9 - 0.7)
        assert ds.notes == [
            "topic '/points': 1 of 5 messages are stamped before the one recorded before "
            "them (up to 0.9 s earlier: recorded out of order, a clock reset, or two "
            "publishers?); the epochs are in stamp order, not the recording's"
        ]


def test_a_part_of_a_split_ros1_recording_names_the_others(tmp_path: Path) -> None:
    """``rosbag record --split`` writes rec_0.bag, rec_1.bag, ...: given rec_0.bag, only its
    part was read, without a word of the rest beside it. It is said, with the merge."""
    import shutil

    _cloud_bag(tmp_path / "rec_0.bag", 1)
    with open_bag(tmp_path / "rec_0.bag") as ds:
        assert ds.notes == []  # alone: no other part
    shutil.copy(tmp_path / "rec_0.bag", tmp_path / "rec_2.bag")
    with open_bag(tmp_path / "rec_2.bag") as ds:
        assert ds.notes == []  # 0 and 2: not rosbag's numbering (run_1.bag, run_2.bag: runs)
    for k in range(1, 11):
        shutil.copy(tmp_path / "rec_0.bag", tmp_path / f"rec_{k}.bag")
    (tmp_path / "rec_x.bag").touch()  # not a part
    with open_bag(tmp_path / "rec_2.bag") as ds:
        assert ds.notes == [
            "rec_0.bag, rec_1.bag, rec_3.bag, rec_4.bag, rec_5.bag, ... (10 in all) beside "
            "rec_2.bag: parts of one split recording? Only rec_2.bag is read; "
            "`rosbags-convert --src rec_0.bag rec_1.bag ... rec_10.bag --dst rec.bag` "
            "merges them into one bag"
        ]


@pytest.mark.parametrize("ros", [1, 2])
def test_a_topic_whose_frame_changes_is_read_in_each_frame_and_said(
    tmp_path: Path, ros: int
) -> None:
    """From sweep 3 on, the lidar's messages name 'velodyne', a frame at the same place (a
    driver relaunched with another frame_id): each message was read in its own frame, as it
    is, but without a word. It is said; the reading is the clean bag's."""
    from dataclasses import replace

    def sweep(k, msg):
        if k < 3:
            return msg
        return replace(msg, header=replace(msg.header, frame_id="velodyne"))

    def tf(bw, k, stamp, msg):
        if k == 0:
            T = bw.transform_stamped(T0_NS, "base_link", "velodyne", T_BASE["lidar"])
            bw.write("/tf_static", bw.tf([T]), stamp + 3_000_000)

    _cloud_bag(bag_path(tmp_path, ros, "clean"), ros)
    _cloud_bag(bag_path(tmp_path, ros, "frames"), ros, extra=tf, sweep=sweep)
    opts = BagOptions(gt_topic="/odom")
    with (
        open_bag(bag_path(tmp_path, ros, "frames"), opts) as ds,
        open_bag(bag_path(tmp_path, ros, "clean"), opts) as clean,
    ):
        _assert_same_reading(ds, clean)
        assert ds.notes == [
            "topic '/points': its messages name 2 frames (lidar, velodyne: a driver "
            "relaunched with another frame_id?); each is read in its own frame, the rig's "
            "sensor origin is lidar's"
        ]
