"""Livox's own point message (``livox_ros_driver`` / ``livox_ros_driver2`` ``CustomMsg``).

Most Livox recordings (the drivers' default for odometry, ``xfer_format`` 1) hold this
message, not a PointCloud2: a header, ``timebase`` (ns since the Unix epoch, the time of
the first point) and a list of points with their ``offset_time`` (ns after ``timebase``),
``line`` (the laser, used as the ring) and ``tag``, Livox's classification of the point:
bits 1-0 by its spatial position and bits 3-2 by its intensity, each 00 normal, 01 "high
confidence noise" (rain, fog, dust, a return on the window), 10 and 11 moderate or low
confidence noise. The points the lidar marks as high confidence noise are left out (and
noted, :func:`livox_noise`), the others kept: the sensor's own verdict, no threshold of
ours; the same holds for Livox's PointCloud2 layout (``tag`` and ``line`` fields,
livox_ros_driver2's ``xfer_format`` 0). A ROS 2 bag without message definitions cannot
decode it, so the definitions (the drivers' public ``.msg`` files) are registered with the
reader's type store by :func:`register_livox_types`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from rosbags.typesys import get_types_from_msg

#: The message types, of the ROS 1 and ROS 2 drivers.
LIVOX_CUSTOM = ("livox_ros_driver/msg/CustomMsg", "livox_ros_driver2/msg/CustomMsg")

_POINT = """uint32 offset_time
float32 x
float32 y
float32 z
uint8 reflectivity
uint8 tag
uint8 line
"""
_MESSAGE = """std_msgs/Header header
uint64 timebase
uint32 point_num
uint8 lidar_id
uint8[3] rsvd
{package}/CustomPoint[] points
"""


def livox_types() -> dict[str, Any]:
    """The ``CustomMsg`` / ``CustomPoint`` definitions of both drivers, for ``register``."""
    types: dict[str, Any] = {}
    for msgtype in LIVOX_CUSTOM:
        package = msgtype.split("/")[0]
        types |= get_types_from_msg(_POINT, f"{package}/msg/CustomPoint")
        types |= get_types_from_msg(_MESSAGE.format(package=package), msgtype)
    return types


def register_livox_types(typestore: Any) -> None:
    """Add the Livox messages to ``typestore`` (a rosbags type store), unless present."""
    known = set(getattr(typestore, "types", {}))
    missing = {name: t for name, t in livox_types().items() if name not in known}
    if missing:
        typestore.register(missing)


def livox_noise(tag: np.ndarray) -> np.ndarray:
    """(n,) bool, the points whose Livox ``tag`` (n,) marks high confidence noise (01 in
    bits 1-0, by spatial position, or in bits 3-2, by intensity)."""
    tag = np.asarray(tag).astype(np.int64)
    return ((tag & 0b11) == 1) | (((tag >> 2) & 0b11) == 1)


def decode_livox(msg: Any, stamp: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """``(points (n, 3), ring (n,) int32, dt (n,) s after ``stamp`` ns, rings)`` of a CustomMsg.

    Points with a non-finite coordinate or exactly at the origin (no return), or marked
    high confidence noise by their ``tag`` (:func:`livox_noise`), are dropped.

    Raises:
        ValueError: ``point_num`` differs from the points the message holds.
    """
    points = msg.points
    if int(msg.point_num) != len(points):
        raise ValueError(
            f"Livox CustomMsg states point_num {int(msg.point_num)} but holds {len(points)} points"
        )
    xyz = np.array([(p.x, p.y, p.z) for p in points], dtype=np.float64).reshape(-1, 3)
    line = np.array([p.line for p in points], dtype=np.int32)
    offset = np.array([p.offset_time for p in points], dtype=np.int64)
    noise = livox_noise(np.array([p.tag for p in points], dtype=np.int64))
    valid = np.all(np.isfinite(xyz), axis=1) & np.any(xyz != 0.0, axis=1) & ~noise
    dt = (int(msg.timebase) - stamp + offset[valid]).astype(np.float64) * 1e-9
    ring = line[valid]
    return xyz[valid], ring, dt, int(ring.max()) + 1 if len(ring) else 0
