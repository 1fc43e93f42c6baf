"""The reference (ground-truth) source of a bag: which it is, and how its poses read.

``gt_topic`` is a pose topic (a ``nav_msgs/Path`` read from its last message), or
``"tf:PARENT:CHILD"`` (:func:`parse_gt`); reading it
(:mod:`planodom.datasets.bag_index`) leaves out a pose with a NaN or infinite value or a
zero quaternion and counts the stamps given twice and the frame pairs its poses name
(:class:`GtReading`), which :func:`gt_notes` says; a reference whose poses name no child
frame (the frame they are of: PoseStamped and PoseWithCovarianceStamped have none) is
read as the base frame's, which :func:`childless_note` says.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader

from planodom.datasets.bag_gt_poses import PATH, path_note
from planodom.datasets.bag_msgs import POSE_TYPES
from planodom.datasets.bag_tf import frame_name
from planodom.errors import DatasetError

#: The message types a gt topic may have: a pose each, or a trajectory whole (read from its
#: last message, :mod:`planodom.datasets.bag_gt_poses`).
GT_TYPES = (*POSE_TYPES, PATH)
#: Prefix of a ``gt_topic`` naming a tf frame pair: ``"tf:PARENT:CHILD"``.
TF_PAIR_PREFIX = "tf:"


@dataclass
class GtReading:
    """How the reference poses of a gt topic read.

    Attributes:
        messages: its poses (messages, or tf values of the tracked edge).
        invalid_example: the first invalid pose's reason (a list of at most one).
        invalid: poses left out: a NaN or infinite value, or a zero quaternion.
        repeated: poses whose stamp and pose repeat an earlier one's (read once).
        conflicting: poses whose stamp repeats an earlier one's with another pose (the last
            of a stamp is used, :func:`planodom.datasets.bag_epochs.interpolate_poses`).
        frames: a pose topic's poses per ``(frame_id, child frame)`` (child "" for the
            pose types without one), in the order first seen.
        path_messages: a ``nav_msgs/Path`` topic's messages (0 for the other types).
        path_recorded: the bag time (ns) of the Path message read, its last with poses.
    """

    messages: int
    invalid_example: list[str] = field(default_factory=list)
    invalid: int = 0
    repeated: int = 0
    conflicting: int = 0
    frames: dict[tuple[str, str], int] = field(default_factory=dict)
    path_messages: int = 0
    path_recorded: int = 0

    def count_repeats(self, times: np.ndarray, poses: np.ndarray) -> None:
        """Count the repeated and conflicting stamps of ``times`` (M,) ns, ``poses`` (M, 4, 4)."""
        order = np.argsort(times, kind="stable")
        t, P = times[order], poses[order]
        again = np.flatnonzero(t[1:] == t[:-1]) + 1
        same = np.all(P[again] == P[again - 1], axis=(1, 2))
        self.repeated = int(same.sum())
        self.conflicting = int((~same).sum())


def parse_gt(reader: AnyReader, path: Path, gt_topic: str | None) -> tuple[str, str] | str | None:
    """The reference source: None, a pose topic name, or a ``(parent, child)`` tf pair."""
    if gt_topic is None:
        return None
    if gt_topic.startswith(TF_PAIR_PREFIX):
        parts = gt_topic[len(TF_PAIR_PREFIX) :].split(":")
        if len(parts) != 2 or not all(parts):
            raise DatasetError(f"{path}: gt '{gt_topic}' must read 'tf:PARENT:CHILD'")
        return frame_name(parts[0]), frame_name(parts[1])
    info = reader.topics.get(gt_topic)
    if info is None:
        poses = sorted(n for n, i in reader.topics.items() if i.msgtype in GT_TYPES)
        raise DatasetError(
            f"{path}: no gt topic '{gt_topic}' (pose topics: {', '.join(poses) or 'none'})"
        )
    if info.msgtype not in GT_TYPES:
        raise DatasetError(
            f"{path}: gt topic '{gt_topic}' is {info.msgtype}, not one of {', '.join(GT_TYPES)}"
        )
    return gt_topic


def gt_notes(gt: GtReading, gt_topic: str | None) -> list[str]:
    """One line each on the reference poses a user should check (see
    :func:`planodom.datasets.bag_notes.bag_notes`)."""
    notes = []
    if gt.path_messages:
        notes.append(path_note(gt_topic, gt.path_messages, gt.messages, gt.path_recorded))
    if gt.invalid:
        notes.append(
            f"gt '{gt_topic}': {gt.invalid} of {gt.messages} poses invalid (the first: "
            f"{gt.invalid_example[0]}), left out: the reference is interpolated across them"
        )
    if len(gt.frames) > 1:
        shown = ", ".join(
            f"{parent} -> {child or '(no child frame)'} ({n})"
            for (parent, child), n in gt.frames.items()
        )
        notes.append(
            f"gt '{gt_topic}': its poses name {len(gt.frames)} frame pairs, {shown} (two "
            "publishers on one topic?); they are read as one trajectory"
        )
    if gt.repeated:
        notes.append(
            f"gt '{gt_topic}': {gt.repeated} of {gt.messages} poses recorded twice (the stamp "
            "and pose of an earlier one), read once"
        )
    if gt.conflicting:
        notes.append(
            f"gt '{gt_topic}': {gt.conflicting} of {gt.messages} poses repeat an earlier "
            "stamp with another pose (two publishers on one topic?); the last of each "
            "stamp is used"
        )
    return notes


def childless_note(
    gt: GtReading,
    gt_topic: str,
    base_frame: str,
    sensors: dict[str, np.ndarray],
    moving: Collection[tuple[str, str]] = (),
) -> str:
    """The note on a reference whose poses name no child frame: read as ``base_frame``'s.

    A PoseStamped's header names the frame its pose is given in, not the frame it is of,
    so neither it nor the bag's tf says which frame that is (a lidar's, an IMU's, a GNSS
    antenna's); a reference of another frame is off by the lever arm between the two.
    ``sensors``: ``T_base_sensor`` (4, 4) of the scans' frames, whose distances from the
    base frame (over 1 mm) the note gives as the size of that lever arm; ``moving``: the
    bag's moving /tf edges ``(parent, child)``, whose children in the poses' frame the note
    offers as a reference (``tf:PARENT:CHILD``) that names its frame.
    """
    parents = sorted({parent for parent, _ in gt.frames} - {""})
    given = f" in '{parents[0]}'" if len(parents) == 1 else ""
    apart = [
        f"'{frame}' {np.linalg.norm(T[:3, 3]):.2f} m"
        for frame, T in sorted(sensors.items())
        if frame != base_frame and np.linalg.norm(T[:3, 3]) > 1e-3
    ]
    arm = f" (from '{base_frame}' the scans' frame {', '.join(apart)} away)" if apart else ""
    tf = sorted(f"tf:{p}:{c}" for p, c in moving if p in parents)
    via = f", or a /tf reference of a named frame ({', '.join(tf)})" if tf else ""
    return (
        f"gt '{gt_topic}': its poses{given} name no child frame (a PoseStamped's do not "
        f"say which frame they are of): read as the base frame '{base_frame}''s poses; if "
        "they are another frame's (the lidar's, an IMU's, a GNSS antenna's), the reference "
        f"is off by the lever arm between the two{arm}: give that frame as --base-frame{via}, "
        "or record an Odometry with its child_frame_id"
    )
