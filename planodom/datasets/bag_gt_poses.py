"""Collecting a reference pose topic's poses message by message (:class:`GtPoses`).

A pose message (:data:`~planodom.datasets.bag_msgs.POSE_TYPES`) gives one pose at its
stamp. A ``nav_msgs/Path`` (:data:`PATH`) gives a whole trajectory in each message: a SLAM
system re-publishes it as it grows and is corrected (at a loop closure), so only its last
message with poses is read, each pose at its own header stamp, in its own header's frame
or else the Path's; the earlier messages are counted, and said (:func:`path_note`).
"""

from __future__ import annotations

from typing import Any

from planodom.datasets.bag_msgs import POSE_STAMPED, decode_pose, stamp_ns
from planodom.datasets.bag_tf import PoseLog, frame_name

#: A trajectory message: the whole path, each pose (``geometry_msgs/PoseStamped``) stamped.
PATH = "nav_msgs/msg/Path"


class GtPoses:
    """The reference poses of a gt topic, from its messages in bag order.

    Attributes:
        log: the valid poses at their stamps (the message's bag time for an unstamped one).
        invalid: why each pose left out was (a NaN or infinite value, a zero quaternion).
        frames: poses per ``(frame_id, child frame)`` (child "" for a type without one).
        child: the first child frame named, or "".
        path_messages: the ``nav_msgs/Path`` messages seen (0 for the other types).
        path_recorded: the bag time (ns) of the Path message read (the last with poses).
    """

    def __init__(self, child: str = "") -> None:
        self.log = PoseLog()
        self.invalid: list[str] = []
        self.frames: dict[tuple[str, str], int] = {}
        self.child = child
        self.path_messages = 0
        self.path_recorded = 0
        self._path: Any = None

    def add(self, msg: Any, msgtype: str, bag_time: int) -> None:
        """Take one message of the gt topic, recorded at ``bag_time`` (ns)."""
        if msgtype == PATH:
            self.path_messages += 1
            if len(msg.poses):
                self._path, self.path_recorded = msg, bag_time
            return
        self._pose(msg, msgtype, bag_time)

    def finish(self) -> None:
        """Read the last Path message with poses, if any (call once, after the last message).

        Raises:
            ValueError: a pose of it without a stamp: the Path does not say when it was.
        """
        if self._path is None:
            return
        poses = self._path.poses
        unstamped = sum(stamp_ns(p.header) == 0 for p in poses)
        if unstamped:
            raise ValueError(
                f"{unstamped} of the {len(poses)} poses of its last nav_msgs/Path message "
                "have no header stamp (0): a Path read as a reference needs each pose's time"
            )
        fallback = frame_name(self._path.header.frame_id)
        for p in poses:
            self._pose(p, POSE_STAMPED, self.path_recorded, fallback)

    def _pose(self, msg: Any, msgtype: str, bag_time: int, frame: str = "") -> None:
        try:
            stamp, T, parent, child = decode_pose(msg, msgtype)
        except ValueError as exc:  # NaN, or a zero quaternion: left out, noted
            self.invalid.append(str(exc))
            return
        self.log.append(stamp or bag_time, T)
        self.child = self.child or child
        key = (parent or frame, child)
        self.frames[key] = self.frames.get(key, 0) + 1


def path_note(gt_topic: str | None, messages: int, poses: int, recorded_ns: int) -> str:
    """The note on a ``nav_msgs/Path`` reference read from its last message with poses."""
    when = f"{recorded_ns // 1_000_000_000}.{recorded_ns % 1_000_000_000 // 1_000_000:03d}"
    return (
        f"gt '{gt_topic}': a nav_msgs/Path (a trajectory published whole): read from its "
        f"last message with poses (recorded at {when} s, {poses} poses at their own stamps); "
        f"its {messages - 1} other message(s) are left out"
    )
