"""Per-point times as other drivers and converters write them, read against the room's
truth: absolute times on another clock than the stamps', offsets counted from the
recording's start, Unix times in a float32, times under a name not read, one time a
sweep. Each refused in one line naming the field, or read and noted."""

from __future__ import annotations

from collections.abc import Callable
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
from planodom.errors import DatasetError

#: A layout: (x, y, z, ring, dt s after the stamp, stamp ns) -> [(name, type, values)].
Layout = Callable[..., list[tuple[str, str, object]]]
_CODES = {"u1": 2, "u2": 4, "i4": 5, "u4": 6, "f4": 7, "f8": 8}
_VELODYNE = np.dtype(
    {
        "names": ["x", "y", "z", "ring", "time"],
        "formats": ["<f4", "<f4", "<f4", "<u2", "<f4"],
        "offsets": [0, 4, 8, 16, 18],
        "itemsize": 22,
    }
)


def _recoded(bw: BagWriter, msg, layout: Layout, codes: dict[str, int] | None = None):
    """The sweep ``msg`` (:func:`lidar_cloud`'s velodyne layout) in ``layout``, 8-byte
    aligned fields, padded to 16 bytes a point (PCL's alignment); ``codes``: PointField
    datatypes to write instead of the true ones, by field name."""
    arr = np.frombuffer(bytes(msg.data), dtype=_VELODYNE)
    stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
    cols = layout(*(arr[c] for c in "xyz"), arr["ring"], arr["time"].astype(np.float64), stamp)
    offsets, end = [], 0
    for _, code, _ in cols:
        size = np.dtype(code).itemsize
        end = -(-end // size) * size
        offsets.append(end)
        end += size
    step = -(-end // 16) * 16
    dtype = np.dtype(
        {
            "names": [c[0] for c in cols],
            "formats": ["<" + c[1] for c in cols],
            "offsets": offsets,
            "itemsize": step,
        }
    )
    out = np.zeros(len(arr), dtype=dtype)
    for name, _, values in cols:
        out[name] = values
    PF = bw.T["sensor_msgs/msg/PointField"]
    fields = [
        PF(name=n, offset=o, datatype=(codes or {}).get(n, _CODES[c]), count=1)
        for (n, c, _), o in zip(cols, offsets, strict=True)
    ]
    return bw.T["sensor_msgs/msg/PointCloud2"](
        header=msg.header,
        height=1,
        width=len(arr),
        fields=fields,
        is_bigendian=False,
        point_step=step,
        row_step=step * len(arr),
        data=np.frombuffer(out.tobytes(), dtype=np.uint8),
        is_dense=False,
    )


def _bag(
    path: Path,
    ros: int,
    layout: Layout,
    codes: dict[str, int] | None = None,
    late: dict[int, int] | None = None,
) -> Path:
    """Six 10 Hz sweeps of the room on /points in ``layout``, with /tf_static and /odom;
    ``late``: ns by sweep number, its header stamp taken that much late after encoding."""
    truth = Truth(T_base_sensor=T_BASE)
    path = path.with_suffix(".bag") if ros == 1 else path
    with BagWriter(path, ros) as bw:
        write_rig_and_odometry(bw, 9)
        for k in range(6):
            stamp = T0_NS + k * 100_000_000
            msg = lidar_cloud(bw, truth, "/points", "lidar", stamp, "velodyne")
            msg = _recoded(bw, msg, layout, codes)
            if late and k in late:
                msg.header = bw.header(stamp + late[k], msg.header.frame_id)
            bw.write("/points", msg, stamp + 2_000_000)
    return path


def _read(path: Path, time_field: str = "auto") -> tuple[float, float, list[str]]:
    """The largest distance of any point (placed by its time along the true trajectory)
    from the room, the smallest span of a sweep's times (s) and the notes."""
    with open_bag(path, BagOptions(gt_topic="/odom", time_field=time_field)) as ds:
        worst, span = 0.0, np.inf
        for k in range(len(ds)):
            scan = ds[k]
            xyz1 = np.append(scan.points, np.ones((len(scan), 1)), 1)[..., None]
            world = true_pose(ds.times[k] + scan.t) @ xyz1
            worst = max(worst, float(distance_to_room(world[:, :3, 0]).max()))
            span = min(span, float(np.ptp(scan.t)))
        return worst, span, list(ds.notes)


def _xyz(x, y, z) -> list[tuple[str, str, object]]:
    return [("x", "f4", x), ("y", "f4", y), ("z", "f4", z), ("intensity", "f4", 0.0)]


def _hesai(clock_s: float) -> Layout:
    """HesaiLidar_ROS_2.0's layout: ``timestamp`` float64 absolute s, on a clock
    ``clock_s`` ahead of the stamps'."""
    return lambda x, y, z, r, t, s: (
        _xyz(x, y, z)
        + [
            ("ring", "u2", r),
            ("timestamp", "f8", s / 1e9 + t + clock_s),
        ]
    )


@pytest.mark.parametrize("ros", [1, 2])
def test_absolute_times_on_another_clock_are_refused(tmp_path: Path, ros: int) -> None:
    """Read before as they were: each sweep deskewed by 0.5 s of motion, 2 m off, no word."""
    worst, span, notes = _read(_bag(tmp_path / "synced", ros, _hesai(0.0)))
    assert worst < 1e-3 and span > 0.09 and notes == []
    late = _bag(tmp_path / "late", ros, _hesai(0.5))
    with pytest.raises(DatasetError) as exc:
        _read(late)
    msg = str(exc.value)
    assert "\n" not in msg and "topic '/points'" in msg and "'timestamp' (float64" in msg
    assert "6 of 6 sweeps" in msg and "another clock" in msg and "--time-field none" in msg
    worst, span, _ = _read(late, "none")  # the way out: every point at its stamp
    assert span == 0.0 and worst < 0.6


def test_a_stamp_taken_late_is_not_another_clock(tmp_path: Path) -> None:
    """A sweep stamped when its last packet arrived (30 ms after its end): read as it is."""
    worst, _, notes = _read(_bag(tmp_path / "late_stamp", 2, _hesai(-0.13)))
    assert worst > 0.0 and notes == []


def test_offsets_from_the_recordings_start_are_refused(tmp_path: Path) -> None:
    """``t`` (uint32 ns) counted from the first sweep's stamp: read before, the sweeps
    after the second deskewed by up to 0.5 s of motion."""

    def layout(x, y, z, r, t, s):
        return _xyz(x, y, z) + [
            ("t", "u4", np.round((s - T0_NS) + t * 1e9)),
            ("ring", "u2", r),
        ]

    with pytest.raises(DatasetError) as exc:
        _read(_bag(tmp_path / "since_start", 2, layout))
    msg = str(exc.value)
    assert "'t' (uint32, read as offsets)" in msg and "3 of 6 sweeps" in msg
    assert "stamped 1700000000.300000000 s" in msg and "recording's start" in msg


def test_unix_times_in_a_float32_are_refused(tmp_path: Path) -> None:
    """A float32 steps by 128 s at 1.7e9 s: read before as one time a sweep up to a minute
    off its stamp (or refused as 10 s off, the unit blamed)."""

    def layout(x, y, z, r, t, s):
        return _xyz(x, y, z) + [
            ("ring", "u2", r),
            ("time", "f4", s / 1e9 + t),
        ]

    with pytest.raises(DatasetError) as exc:
        _read(_bag(tmp_path / "f4", 1, layout))
    assert "'time' (float32) holds absolute times (1.7e+09 s)" in str(exc.value)
    assert "steps of 128 s" in str(exc.value)


def test_times_under_another_name_are_noted_and_read_when_named(tmp_path: Path) -> None:
    """A converter's Livox layout (``time_offset`` ns from ``timebase_low`` / ``_high``):
    read before without a word, its sweeps not deskewed."""

    def layout(x, y, z, r, t, s):
        return _xyz(x, y, z) + [
            ("ring", "u1", r),
            ("timebase_low", "u4", s % 2**32),
            ("timebase_high", "u4", s >> 32),
            ("time_offset", "u4", np.round(t * 1e9)),
        ]

    bag = _bag(tmp_path / "converted", 2, layout)
    worst, span, notes = _read(bag)
    assert span == 0.0 and worst > 0.3  # not deskewed
    (note,) = notes
    assert note.startswith("topic '/points': 6 of 6 clouds have none of the time fields read")
    assert "'timebase_low' (uint32), 'timebase_high' (uint32), 'time_offset' (uint32)" in note
    worst, span, notes = _read(bag, "time_offset")
    assert worst < 1e-3 and span > 0.09 and notes == []


def test_a_time_field_of_a_type_not_read_is_noted(tmp_path: Path) -> None:
    """``t`` written with PointField datatype 9 (no ROS type): skipped without a word."""

    def layout(x, y, z, r, t, s):
        return _xyz(x, y, z) + [
            ("t", "u4", np.round(t * 1e9)),
            ("ring", "u2", r),
        ]

    _, _, notes = _read(_bag(tmp_path / "t9", 2, layout, {"t": 9}))
    (note,) = notes
    assert "but 't' (PointField type 9, not read): their sweeps are not deskewed" in note
    assert note.endswith("not deskewed")


@pytest.mark.parametrize("name, kind", [("time", "f4"), ("timestamp", "f8")])
def test_one_time_for_all_the_points_of_each_sweep_is_noted(
    tmp_path: Path, name: str, kind: str
) -> None:
    """Every point at 0 s, or at the stamp as an absolute time: not deskewed, no word."""

    def layout(x, y, z, r, t, s):
        return _xyz(x, y, z) + [
            ("ring", "u2", r),
            (name, kind, 0.0 * t + (s / 1e9 if name == "timestamp" else 0.0)),
        ]

    _, span, notes = _read(_bag(tmp_path / "flat", 2, layout))
    assert span == 0.0
    (note,) = notes
    assert f"'{name}' ({np.dtype(kind).name}) holds one value for all the points" in note


@pytest.mark.parametrize("timebase_ns, message", [
    (500_000_000, "Livox CustomMsg point times (timebase + offset_time) put 3 of 3 sweeps"),
    (-T0_NS + 120 * 10**9, "Livox CustomMsg's timebase + offset_time put a point -1.7e+09 s"),
])  # fmt: skip
def test_livox_times_on_another_clock_are_refused(
    tmp_path: Path, timebase_ns: int, message: str
) -> None:
    """A CustomMsg's ``timebase`` 0.5 s off its stamp, or the lidar's uptime (120 s) while
    the messages carry Unix stamps: read before, each point deskewed by that much motion
    (1.7e9 s), no word."""
    from tests.datasets import test_bag_livox as livox

    def shifted(*args, **kwargs):
        msg = custom(*args, **kwargs)
        msg.timebase = int(msg.timebase) + timebase_ns
        return msg

    custom = livox._custom_msg
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(livox, "_custom_msg", shifted)
        sweeps = livox._sweeps(np.random.default_rng(2))
        livox._write(tmp_path / "l", 2, livox.LIVOX_CUSTOM[1], sweeps)
    with pytest.raises(DatasetError) as exc:
        open_bag(tmp_path / "l", BagOptions())
    assert message in str(exc.value) and "--time-field none" in str(exc.value)
    with open_bag(tmp_path / "l", BagOptions(time_field="none")) as ds:
        assert len(ds) == 3 and not ds[0].t.any()


def test_a_few_sweeps_stamped_late_are_noted_and_read(tmp_path: Path) -> None:
    """Two of six sweeps 0.35 s before their stamps (receipt times of a recorder that
    stalled): their absolute times are right, so they are read, and noted."""

    late = {2: 350_000_000, 3: 350_000_000}
    worst, _, notes = _read(_bag(tmp_path / "stalled", 2, _hesai(0.0), late=late))
    assert worst < 1e-3
    (note,) = [n for n in notes if "away from their stamps" in n]  # and the stamp order's
    assert "puts 2 of 6 sweeps away from their stamps" in note and "-0.35 to -0.25 s" in note
    assert note.endswith("stamps taken late (a recorder stalled?); read as they are")


def _firing_order(r: np.ndarray) -> np.ndarray:
    """A 16-beam lidar's elevation ranks ``r`` (n,) as laser ids in firing order (a
    VLP-16's: ids 0, 2, ..., 14 the lower half from the bottom, 1, 3, ..., 15 the upper)."""
    r = r.astype(np.int64)
    return np.where(r < 8, 2 * r, 2 * (r - 8) + 1)


@pytest.mark.parametrize("ros", [1, 2])
def test_ring_ids_in_firing_order_are_renumbered_by_elevation(tmp_path: Path, ros: int) -> None:
    """Read before in id order: the range image's neighbouring rows 16 deg apart (a
    simulated 16-beam lidar's ATE 0.003 m -> 9.3 m), no word. Now each point's ring is
    its beam's elevation rank, as the driver's ring field in elevation order reads."""

    def velodyne(x, y, z, r, t, s):
        return _xyz(x, y, z) + [("ring", "u2", r), ("time", "f4", t)]

    def firing(x, y, z, r, t, s):
        return _xyz(x, y, z) + [("ring", "u2", _firing_order(r)), ("time", "f4", t)]

    def rings_by_point(path: Path) -> tuple[np.ndarray, list[str]]:
        with open_bag(path, BagOptions(gt_topic="/odom")) as ds:
            out = []
            for k in range(len(ds)):
                scan = ds[k]
                order = np.lexsort(scan.points.T)
                out.append(scan.ring[order])
            return np.concatenate(out), list(ds.notes)

    truth, notes = rings_by_point(_bag(tmp_path / "elevation", ros, velodyne))
    assert notes == []
    got, notes = rings_by_point(_bag(tmp_path / "firing", ros, firing))
    np.testing.assert_array_equal(got, truth)
    (note,) = notes
    assert "ring ids do not follow its beams' elevations (ring 0: -15.0, 1: +1.0, 2: -13.0" in note


def test_ring_ids_of_lidars_merged_are_kept_and_noted(tmp_path: Path) -> None:
    """Two lidars' rings merged into one cloud (ids 0..7 one's beams, 8..15 the other's,
    each block in elevation order): not interleaved by elevation, noted."""

    def merged(x, y, z, r, t, s):
        ids = np.where(r % 2 == 0, r // 2, 8 + r // 2)
        return _xyz(x, y, z) + [("ring", "u2", ids), ("time", "f4", t)]

    with open_bag(_bag(tmp_path / "merged", 2, merged), BagOptions(gt_topic="/odom")) as ds:
        scan, notes = ds[0], list(ds.notes)
    z = np.arctan2(scan.points[:, 2], np.hypot(scan.points[:, 0], scan.points[:, 1]))
    means = [z[scan.ring == i].mean() for i in range(16)]
    assert np.all(np.diff(means[:8]) > 0) and np.all(np.diff(means[8:]) > 0)
    (note,) = notes
    assert "runs of up to 8 rings in elevation order: several lidars merged?" in note
