"""Small ROS 1 / ROS 2 bags written with rosbags itself, from a known scene and motion.

The scene is a closed box room; the vehicle drives through it with a known pose
``T_world_base(t)``. Every beam is cast in the world at its own acquisition time from the
sensor pose at that time, so the points the reader returns can be checked against the
truth: transformed with the true pose at ``epoch time + t`` they must lie on the room's
walls, and they must equal the true hits expressed in the base frame at that time.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from scipy.spatial.transform import Rotation

from planodom.geometry import invert_transform

TF_MESSAGE = "tf2_msgs/msg/TFMessage"
T0_NS = 1_700_000_000 * 1_000_000_000  # bag start, ns since the Unix epoch
#: The room: planes n . x = d with outward normals n (inside: n . x < d).
ROOM_NORMALS = np.array(
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float
)
ROOM_OFFSETS = np.array([12.0, 10.0, 8.0, 7.0, 4.0, 0.0])


def pose(roll: float, pitch: float, yaw: float, xyz: tuple[float, float, float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", [roll, pitch, yaw]).as_matrix()
    T[:3, 3] = xyz
    return T


def true_pose(t: np.ndarray | float) -> np.ndarray:
    """``T_world_base`` (..., 4, 4) at absolute times ``t`` (s since the Unix epoch)."""
    tau = np.asarray(t, dtype=np.float64) - T0_NS / 1e9
    T = np.zeros(tau.shape + (4, 4))
    rpy = np.stack([0.02 * np.sin(2 * tau), 0.015 * np.cos(tau), 0.4 * tau], axis=-1)
    T[..., :3, :3] = (
        Rotation.from_euler("xyz", rpy.reshape(-1, 3)).as_matrix().reshape(tau.shape + (3, 3))
    )
    T[..., 0, 3] = -3.0 + 1.5 * tau
    T[..., 1, 3] = 0.3 * np.sin(tau)
    T[..., 2, 3] = 0.2
    T[..., 3, 3] = 1.0
    return T


def cast(origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Range (n,) of each ray to the room's walls (rays start inside)."""
    along = dirs @ ROOM_NORMALS.T
    gap = ROOM_OFFSETS[None] - origins @ ROOM_NORMALS.T
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(along > 1e-12, gap / along, np.inf)
    return s.min(axis=1)


def distance_to_room(points_world: np.ndarray) -> np.ndarray:
    """Distance (n,) of world points to the nearest wall."""
    return np.abs(points_world @ ROOM_NORMALS.T - ROOM_OFFSETS[None]).min(axis=1)


@dataclass
class Truth:
    """What was written: per topic, the truth points and their absolute times."""

    T_base_sensor: dict[str, np.ndarray] = field(default_factory=dict)
    stamps: dict[str, list[int]] = field(default_factory=dict)
    times: dict[str, list[np.ndarray]] = field(default_factory=dict)  # abs s per point
    world: dict[str, list[np.ndarray]] = field(default_factory=dict)  # true hits


class BagWriter:
    """A ROS 1 or ROS 2 bag writer with the message helpers the tests need."""

    def __init__(self, path: Path, ros: int, storage: str = "sqlite3") -> None:
        self.ros = ros
        self.ts = get_typestore(Stores.ROS1_NOETIC if ros == 1 else Stores.ROS2_HUMBLE)
        if ros == 1:  # noetic's store lacks tf2_msgs
            self.ts.register(
                get_types_from_msg("geometry_msgs/TransformStamped[] transforms", TF_MESSAGE)
            )
        if ros == 1:
            self.writer: Any = Writer1(path)
        else:
            plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
            self.writer = Writer2(path, version=9, storage_plugin=plugin)
        self.conns: dict[str, Any] = {}
        self.T = self.ts.types

    def __enter__(self) -> BagWriter:
        self.writer.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.writer.close()

    def write(self, topic: str, msg: Any, bag_ns: int) -> None:
        if topic not in self.conns:
            self.conns[topic] = self.writer.add_connection(
                topic, msg.__msgtype__, typestore=self.ts
            )
        ser = self.ts.serialize_ros1 if self.ros == 1 else self.ts.serialize_cdr
        self.writer.write(self.conns[topic], bag_ns, ser(msg, msg.__msgtype__))

    def header(self, stamp: int, frame: str) -> Any:
        time = self.T["builtin_interfaces/msg/Time"](sec=stamp // 10**9, nanosec=stamp % 10**9)
        if self.ros == 1:
            return self.T["std_msgs/msg/Header"](seq=0, stamp=time, frame_id=frame)
        return self.T["std_msgs/msg/Header"](stamp=time, frame_id=frame)

    def geometry(self, T: np.ndarray) -> tuple[Any, Any]:
        q = Rotation.from_matrix(T[:3, :3]).as_quat()
        quat = self.T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3])
        return T[:3, 3], quat

    def transform_stamped(self, stamp: int, parent: str, child: str, T: np.ndarray) -> Any:
        t, q = self.geometry(T)
        vec = self.T["geometry_msgs/msg/Vector3"](x=t[0], y=t[1], z=t[2])
        tr = self.T["geometry_msgs/msg/Transform"](translation=vec, rotation=q)
        return self.T["geometry_msgs/msg/TransformStamped"](
            header=self.header(stamp, parent), child_frame_id=child, transform=tr
        )

    def tf(self, transforms: list[Any]) -> Any:
        return self.T["tf2_msgs/msg/TFMessage"](transforms=transforms)

    def odometry(self, stamp: int, T: np.ndarray) -> Any:
        t, q = self.geometry(T)
        point = self.T["geometry_msgs/msg/Point"](x=t[0], y=t[1], z=t[2])
        p = self.T["geometry_msgs/msg/Pose"](position=point, orientation=q)
        pwc = self.T["geometry_msgs/msg/PoseWithCovariance"](pose=p, covariance=np.zeros(36))
        vec = self.T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        tw = self.T["geometry_msgs/msg/Twist"](linear=vec, angular=vec)
        twc = self.T["geometry_msgs/msg/TwistWithCovariance"](twist=tw, covariance=np.zeros(36))
        return self.T["nav_msgs/msg/Odometry"](
            header=self.header(stamp, "odom"), child_frame_id="base_link", pose=pwc, twist=twc
        )


def laser_scan(bw: BagWriter, truth: Truth, topic: str, frame: str, stamp: int) -> Any:
    """A LaserScan of the scanner ``frame`` starting at ``stamp``, its beams cast in the room."""
    a0, inc, dt = np.float32(-2.0), np.float32(0.01), np.float32(1e-4)
    n = 400
    i = np.arange(n)
    angles = float(a0) + i * float(inc)
    times = stamp / 1e9 + i * float(dt)
    T_ws = true_pose(times) @ truth.T_base_sensor[frame]
    dirs_s = np.column_stack([np.cos(angles), np.sin(angles), np.zeros(n)])
    dirs_w = np.einsum("nij,nj->ni", T_ws[:, :3, :3], dirs_s)
    ranges = cast(T_ws[:, :3, 3], dirs_w).astype(np.float32)
    ranges[::37] = np.inf  # no returns
    ranges[5] = 0.01  # below range_min
    ok = np.isfinite(ranges) & (ranges >= 0.05)
    hits = T_ws[:, :3, 3] + dirs_w * ranges.astype(np.float64)[:, None]
    truth.stamps.setdefault(topic, []).append(stamp)
    truth.times.setdefault(topic, []).append(times[ok])
    truth.world.setdefault(topic, []).append(hits[ok])
    return bw.T["sensor_msgs/msg/LaserScan"](
        header=bw.header(stamp, frame),
        angle_min=float(a0),
        angle_max=float(a0 + inc * (n - 1)),
        angle_increment=float(inc),
        time_increment=float(dt),
        scan_time=0.1,
        range_min=0.05,
        range_max=40.0,
        ranges=ranges,
        intensities=np.zeros(n, dtype=np.float32),
    )


def lidar_cloud(
    bw: BagWriter, truth: Truth, topic: str, frame: str, stamp: int, layout: str = "velodyne"
) -> Any:
    """A 16-ring PointCloud2 sweep. ``velodyne``: unorganised, ``time`` float32 s, 22-byte
    points; ``ouster``: organised 16 rows with row padding, ``t`` uint32 ns. With the suffix
    ``_ms`` / ``_us`` the time field is in milliseconds / microseconds instead (the columns
    then whole microseconds apart)."""
    layout, _, unit = layout.partition("_")
    rings, cols = 16, 240
    elev = np.deg2rad(np.linspace(-15, 15, rings))
    az = np.arange(cols) * 2 * np.pi / cols
    E, A = np.meshgrid(elev, az, indexing="ij")  # (rings, cols)
    step_ns = 100_000_000 // cols // 1000 * 1000 if unit == "us" else 100_000_000 // cols
    col_dt_ns = np.broadcast_to((np.arange(cols) * step_ns)[None], E.shape)
    times = (stamp + col_dt_ns) / 1e9
    T_ws = true_pose(times.ravel()) @ truth.T_base_sensor[frame]
    dirs_s = np.stack([np.cos(E) * np.cos(A), np.cos(E) * np.sin(A), np.sin(E)], -1).reshape(-1, 3)
    dirs_w = np.einsum("nij,nj->ni", T_ws[:, :3, :3], dirs_s)
    r = cast(T_ws[:, :3, 3], dirs_w)
    xyz = (dirs_s * r[:, None]).astype(np.float32)
    ok = np.ones(len(r), dtype=bool)
    ok[::53] = False
    xyz[~ok] = np.nan if layout == "velodyne" else 0.0
    ring = np.repeat(np.arange(rings), cols)
    hits = T_ws[:, :3, 3] + dirs_w * np.linalg.norm(xyz.astype(np.float64), axis=1)[:, None]
    truth.stamps.setdefault(topic, []).append(stamp)
    truth.times.setdefault(topic, []).append(times.ravel()[ok])
    truth.world.setdefault(topic, []).append(hits[ok])
    PF = bw.T["sensor_msgs/msg/PointField"]
    if layout == "velodyne":
        names = ["x", "y", "z", "intensity", "ring", "time"]
        fmts = ["<f4", "<f4", "<f4", "<f4", "<u2", "<f4"]
        codes, offsets, step = [7, 7, 7, 7, 4, 7], [0, 4, 8, 12, 16, 18], 22
        tvals = (col_dt_ns.ravel() / (1e6 if unit == "ms" else 1e9)).astype(np.float32)
        height, width, pad = 1, rings * cols, 0
    else:
        names = ["x", "y", "z", "t", "ring"]
        fmts = ["<f4", "<f4", "<f4", "<u4", "<u2"]
        codes, offsets, step = [7, 7, 7, 6, 4], [0, 4, 8, 16, 20], 24
        tvals = (col_dt_ns.ravel() // (1000 if unit == "us" else 1)).astype(np.uint32)
        height, width, pad = rings, cols, 8
    dtype = np.dtype({"names": names, "formats": fmts, "offsets": offsets, "itemsize": step})
    arr = np.zeros(rings * cols, dtype=dtype)
    for c, name in enumerate("xyz"):
        arr[name] = xyz[:, c]
    arr["ring"] = ring
    arr["t" if layout != "velodyne" else "time"] = tvals
    raw = arr.tobytes()
    row = width * step
    data = b"".join(raw[k * row : (k + 1) * row] + bytes(pad) for k in range(height))
    fields = [
        PF(name=n, offset=o, datatype=c, count=1)
        for n, o, c in zip(names, offsets, codes, strict=True)
    ]
    return bw.T["sensor_msgs/msg/PointCloud2"](
        header=bw.header(stamp, frame),
        height=height,
        width=width,
        fields=fields,
        is_bigendian=False,
        point_step=step,
        row_step=row + pad,
        data=np.frombuffer(data, dtype=np.uint8),
        is_dense=False,
    )


@dataclass
class Sensor:
    """A scanner of the simulated rig: topic, frame, phase (ns) after the 10 Hz tick, kind."""

    topic: str
    frame: str
    phase_ns: int
    kind: str = "scan"  # "scan" | "velodyne" | "ouster" (| "_ms" / "_us", lidar_cloud)


def write_bag(
    path: Path,
    ros: int,
    sensors: list[Sensor],
    static_tf: list[tuple[str, str, np.ndarray]],
    T_base_sensor: dict[str, np.ndarray],
    *,
    storage: str = "sqlite3",
    duration_s: float = 1.2,
    odom: bool = True,
    tf_odom: bool = False,
    extra: Callable[[BagWriter], None] | None = None,
) -> Truth:
    """Write a bag: /tf_static, sensors at 10 Hz, /odom (Odometry) at 200 Hz, optional /tf."""
    truth = Truth(T_base_sensor=T_base_sensor)
    with BagWriter(path, ros, storage) as bw:
        bw.write(
            "/tf_static",
            bw.tf([bw.transform_stamped(T0_NS, p, c, T) for p, c, T in static_tf]),
            T0_NS,
        )
        events: list[tuple[int, int, str, Any]] = []
        for k in range(int(duration_s * 10)):
            for s in sensors:
                stamp = T0_NS + k * 100_000_000 + s.phase_ns
                events.append((stamp + 2_000_000, 1, s.topic, (s, stamp)))  # 2 ms latency
        if odom:
            for k in range(int(duration_s * 200) + 40):
                stamp = T0_NS - 100_000_000 + k * 5_000_000
                events.append((stamp, 0, "/odom", bw.odometry(stamp, true_pose(stamp / 1e9))))
        if tf_odom:
            for k in range(int(duration_s * 100) + 20):
                stamp = T0_NS - 100_000_000 + k * 10_000_000
                tr = bw.transform_stamped(stamp, "odom", "base_link", true_pose(stamp / 1e9))
                events.append((stamp, 0, "/tf", bw.tf([tr])))
        for bag_ns, kind, topic, item in sorted(events, key=lambda e: (e[0], e[1], e[2])):
            if kind == 1:
                s, stamp = item
                msg = (
                    laser_scan(bw, truth, topic, s.frame, stamp)
                    if s.kind == "scan"
                    else lidar_cloud(bw, truth, topic, s.frame, stamp, s.kind)
                )
                bw.write(topic, msg, bag_ns)
            else:
                bw.write(topic, item, bag_ns)
        if extra is not None:
            extra(bw)
    return truth


# the rig: three tilted 2D scanners, two of them behind intermediate frames
T_FP_BL = pose(0, 0, 0, (0.0, 0.0, 0.1))  # base_footprint -> base_link
T_BL_MOUNT = pose(0, 0, 0.2, (0.6, 0.0, 0.9))
T_BASE = {
    "laser_front": pose(0.0, 0.35, 0.0, (0.8, 0.0, 1.0)),
    "laser_left": pose(0.5, 0.0, 1.57, (0.0, 0.4, 1.1)),
    "laser_rear": pose(0.0, 0.3, 3.14159, (-0.7, 0.0, 0.95)),
    "lidar": pose(0.0, 0.05, 0.3, (0.1, 0.0, 1.6)),
}
STATIC_TF = [
    ("base_footprint", "base_link", T_FP_BL),
    ("base_link", "mount", T_BL_MOUNT),
    ("mount", "laser_front", invert_transform(T_BL_MOUNT) @ T_BASE["laser_front"]),
    ("base_link", "laser_left", T_BASE["laser_left"]),
    ("base_footprint", "laser_rear", T_FP_BL @ T_BASE["laser_rear"]),
    ("base_link", "lidar", T_BASE["lidar"]),
]
SCANNERS = [
    Sensor("/scan_front", "laser_front", 0),
    Sensor("/scan_left", "laser_left", 33_000_000),
    Sensor("/scan_rear", "laser_rear", 66_000_000),
]


def write_rig_and_odometry(bw: BagWriter, last: int) -> None:
    """/tf_static (:data:`STATIC_TF`) and /odom on the 100 ms grid, from one period before
    T0_NS to ``last - 1`` periods after it (the true pose at each stamp)."""
    bw.write("/tf_static", bw.tf([bw.transform_stamped(T0_NS, *e) for e in STATIC_TF]), T0_NS)
    for k in range(-1, last):
        odom = T0_NS + k * 100_000_000
        bw.write("/odom", bw.odometry(odom, true_pose(odom / 1e9)), odom)


def split_ros2_bag(src: Path, dst: Path, cuts: list[int], storage: str = "sqlite3") -> None:
    """Write the ROS 2 bag ``src`` again as a split recording ``dst`` (as ``ros2 bag record
    --max-bag-size`` leaves one): the messages recorded before ``cuts[0]`` (ns) in
    ``dst/<name>_0``, then up to ``cuts[1]`` in ``_1``, ..., one ``metadata.yaml`` listing
    every part."""
    from rosbags.rosbag2 import Reader as Reader2
    from ruamel.yaml import YAML

    ts = get_typestore(Stores.ROS2_HUMBLE)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    parts = [dst.parent / f"{dst.name}_{k}" for k in range(len(cuts) + 1)]
    writers = [Writer2(p, version=9, storage_plugin=plugin) for p in parts]
    with Reader2(src) as reader:
        for w in writers:
            w.open()
        conns: list[dict[int, Any]] = [{} for _ in writers]
        for conn, bag_ns, raw in reader.messages():
            k = sum(bag_ns >= c for c in cuts)
            if conn.id not in conns[k]:
                conns[k][conn.id] = writers[k].add_connection(
                    conn.topic, conn.msgtype, typestore=ts
                )
            writers[k].write(conns[k][conn.id], bag_ns, raw)
        for w in writers:
            w.close()
    yaml = YAML(typ="safe")
    metas = [
        yaml.load((p / "metadata.yaml").read_text())["rosbag2_bagfile_information"] for p in parts
    ]
    dst.mkdir()
    ext = ".mcap" if storage == "mcap" else ".db3"
    topics: dict[str, Any] = {}
    for k, (part, meta) in enumerate(zip(parts, metas, strict=True)):
        (part / f"{part.name}{ext}").rename(dst / f"{dst.name}_{k}{ext}")
        meta["files"][0]["path"] = f"{dst.name}_{k}{ext}"
        for t in meta["topics_with_message_count"]:
            name = t["topic_metadata"]["name"]
            if name in topics:
                topics[name]["message_count"] += t["message_count"]
            else:
                topics[name] = t
        (part / "metadata.yaml").unlink()
        part.rmdir()
    merged = dict(metas[0])
    merged["files"] = [m["files"][0] for m in metas]
    merged["relative_file_paths"] = [f["path"] for f in merged["files"]]
    merged["message_count"] = sum(m["message_count"] for m in metas)
    merged["topics_with_message_count"] = list(topics.values())
    with open(dst / "metadata.yaml", "w") as f:
        yaml.dump({"rosbag2_bagfile_information": merged}, f)
