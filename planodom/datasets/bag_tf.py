"""The transform tree of a bag: extrinsics from ``/tf_static`` and ``/tf``, tf trajectories.

Edges are ``T_parent_child`` (4, 4) float64 (``p_parent = T_parent_child p_child``), keyed
by ``(parent, child)`` frame names with any leading ``/`` removed. ``/tf_static`` edges are
rigid by definition; a ``/tf`` edge counts as rigid (an extrinsic) while every message
repeats its first value to within 1 micrometre / 1 microradian, and as moving otherwise
(``odom -> base_link``). Extrinsics are chained through rigid edges only, in either
direction (up to a common ancestor and down again).

A transform with a NaN or infinite value, or a quaternion whose squared norm is 0.01 or
more off 1 (a zero quaternion, angles written where a quaternion goes), is ignored, as
tf2 ignores it (``TF_NAN_INPUT``, ``TF_DENORMALIZED_QUATERNION``), and counted per edge
for a note (:meth:`TfTree.ignored_notes`): a robot arm's servo or a visual odometry that
lost track publishes such transforms of frames the vehicle does not need.
"""

from __future__ import annotations

from array import array
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from planodom.errors import DatasetError
from planodom.geometry import invert_transform

TF_TOPIC = "/tf"
TF_STATIC_TOPIC = "/tf_static"
#: Largest change of a /tf edge (metres, radians) for which it still counts as rigid.
RIGID_TOL = 1e-6
#: Largest disagreement (metres, radians) of two rigid chains between two frames that is
#: not reported as a loop: 1 mm / 1 mrad, a hand-written extrinsic's rounding.
LOOP_TOL = 1e-3
#: tf2's tolerance on a quaternion's squared norm (``QUATERNION_NORMALIZATION_TOLERANCE =
#: 10e-3`` in tf2's buffer_core, ROS 1 and 2): a transform whose ``|x² + y² + z² + w² - 1|``
#: reaches it is ignored by tf2, so by every node of the recording. Not fitted: tf2's.
QUATERNION_NORM2_TOL = 10e-3


def frame_name(name: str) -> str:
    """A tf frame name without the leading ``/`` older ROS 1 bags carry."""
    return name.lstrip("/")


def transform_from_msg(translation: Any, rotation: Any) -> np.ndarray:
    """``T`` (4, 4) from a ROS ``Vector3``/``Point`` and a ``Quaternion`` (normalised).

    Raises:
        ValueError: the quaternion is zero or not finite, or its squared norm is
            :data:`QUATERNION_NORM2_TOL` or more off 1 (tf2 would ignore it), or the
            translation is not finite.
    """
    q = np.array([rotation.x, rotation.y, rotation.z, rotation.w], dtype=np.float64)
    norm = float(np.linalg.norm(q))
    if not np.isfinite(norm) or norm < 1e-9:
        raise ValueError(f"invalid quaternion {q.tolist()}")
    if abs(norm * norm - 1.0) >= QUATERNION_NORM2_TOL:
        shown = ", ".join(f"{v:.4g}" for v in q)
        raise ValueError(
            f"quaternion ({shown}) of norm {norm:.4g} is no unit quaternion (tf2 ignores one "
            f"whose squared norm is {QUATERNION_NORM2_TOL:g} or more off 1; angles written "
            "where a quaternion goes?)"
        )
    t = np.array([translation.x, translation.y, translation.z], dtype=np.float64)
    if not np.isfinite(t).all():
        raise ValueError(f"invalid translation {t.tolist()}")
    T = np.eye(4)
    T[:3, :3] = Rotation.from_quat(q / norm).as_matrix()
    T[:3, 3] = t
    return T


def _same_transform(A: np.ndarray, B: np.ndarray) -> bool:
    """True when ``A`` and ``B`` differ by at most :data:`RIGID_TOL` (m and rad)."""
    if np.linalg.norm(A[:3, 3] - B[:3, 3]) > RIGID_TOL:
        return False
    cos = (np.trace(A[:3, :3].T @ B[:3, :3]) - 1.0) / 2.0
    return float(np.arccos(np.clip(cos, -1.0, 1.0))) <= RIGID_TOL


class PoseLog:
    """Stamped poses appended one by one in compact storage (20 doubles' worth per pose)."""

    def __init__(self) -> None:
        self._times = array("q")
        self._poses = array("d")

    def __len__(self) -> int:
        return len(self._times)

    def append(self, stamp_ns: int, T: np.ndarray) -> None:
        """Add ``T`` (4, 4) at ``stamp_ns`` (int ns)."""
        self._times.append(int(stamp_ns))
        self._poses.extend(np.asarray(T, dtype=np.float64)[:3].reshape(-1).tolist())

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """``(times (M,) int64 ns, poses (M, 4, 4) float64)``."""
        times = np.frombuffer(self._times, dtype=np.int64).copy()
        poses = np.zeros((len(times), 4, 4))
        poses[:, :3] = np.frombuffer(self._poses, dtype=np.float64).reshape(-1, 3, 4)
        poses[:, 3, 3] = 1.0
        return times, poses


@dataclass
class TfTree:
    """The rigid and moving edges of a bag's tf, built message by message with :meth:`add`.

    Attributes:
        rigid: ``(parent, child) -> T_parent_child`` of the edges usable as extrinsics.
        moving: ``(parent, child)`` of the /tf edges whose value changes over the bag.
        tracked: the ``(parent, child)`` edge whose every value is kept (for a tf-pair
            ground truth), or None.
        track: the tracked edge's values ``T_parent_child`` at their stamps.
        restated: per ``/tf_static`` edge given another value later in the bag, how many
            times, and the largest distance (m) and angle (rad) from its first value.
        ignored: per ``(topic, parent, child)``, the transforms left out for an invalid
            value (as tf2 leaves them out) and why the first was.
    """

    rigid: dict[tuple[str, str], np.ndarray] = field(default_factory=dict)
    moving: set[tuple[str, str]] = field(default_factory=set)
    static_edges: set[tuple[str, str]] = field(default_factory=set)
    tracked: tuple[str, str] | None = None
    track: PoseLog = field(default_factory=PoseLog)
    restated: dict[tuple[str, str], tuple[int, float, float]] = field(default_factory=dict)
    ignored: dict[tuple[str, str, str], tuple[int, str]] = field(default_factory=dict)
    _first_static: dict[tuple[str, str], np.ndarray] = field(default_factory=dict)

    def add(self, msg: Any, static: bool) -> None:
        """Add the transforms of one ``tf2_msgs/TFMessage`` (from /tf_static when
        ``static``); one with an invalid value is left out and counted in ``ignored``."""
        for tr in msg.transforms:
            edge = (frame_name(tr.header.frame_id), frame_name(tr.child_frame_id))
            try:
                T = transform_from_msg(tr.transform.translation, tr.transform.rotation)
            except ValueError as exc:
                key = (TF_STATIC_TOPIC if static else TF_TOPIC, *edge)
                n, why = self.ignored.get(key, (0, str(exc)))
                self.ignored[key] = (n + 1, why)
                continue
            if edge == self.tracked:
                stamp = tr.header.stamp
                self.track.append(int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec), T)
            if static:
                self._restate(edge, T)
                self.static_edges.add(edge)
                self.rigid[edge] = T
                self.moving.discard(edge)
            elif edge in self.static_edges or edge in self.moving:
                continue
            elif edge not in self.rigid:
                self.rigid[edge] = T
            elif not _same_transform(self.rigid[edge], T):
                del self.rigid[edge]
                self.moving.add(edge)

    def _restate(self, edge: tuple[str, str], T: np.ndarray) -> None:
        """Count a static edge's value ``T`` that differs from the one before it."""
        if edge not in self.static_edges:
            self._first_static[edge] = T
            return
        if _same_transform(self.rigid[edge], T):
            return
        D = invert_transform(self._first_static[edge]) @ T
        dist = float(np.linalg.norm(D[:3, 3]))
        angle = float(np.arccos(np.clip((np.trace(D[:3, :3]) - 1) / 2, -1, 1)))
        n, d0, a0 = self.restated.get(edge, (0, 0.0, 0.0))
        self.restated[edge] = (n + 1, max(d0, dist), max(a0, angle))

    def restated_notes(self) -> list[str]:
        """One line for each ``/tf_static`` edge given several values (two static publishers
        of one frame, or an extrinsic set again mid-bag): the last value is used throughout,
        as tf2 would use it after its message."""
        return [
            f"/tf_static: '{parent}' -> '{child}' is given another value {n} time(s), up to "
            f"{dist:.3f} m and {np.degrees(angle):.2f} deg from its first (two static "
            "publishers of one frame, or an extrinsic set again mid-bag?); the last is used "
            "for the whole bag"
            for (parent, child), (n, dist, angle) in sorted(self.restated.items())
        ]

    def ignored_notes(self) -> list[str]:
        """One line for each edge some of whose transforms were left out (``ignored``)."""
        return [
            f"{topic}: {n} transform(s) '{parent}' -> '{child}' ignored, as tf2 ignores them "
            f"(the first: {why})"
            for (topic, parent, child), (n, why) in sorted(self.ignored.items())
        ]

    def frames(self) -> list[str]:
        """Every frame named by a rigid or moving edge, sorted."""
        names = {f for edge in (*self.rigid, *self.moving) for f in edge}
        return sorted(names)

    def lookup(self, target: str, source: str) -> np.ndarray | None:
        """``T_target_source`` (4, 4) through rigid edges, or None when they do not connect
        (through a loop, the chain of fewest links: :meth:`loops` says whether they agree)."""
        target, source = frame_name(target), frame_name(source)
        if target == source:
            return np.eye(4)
        return self._reach(target)[0].get(source)

    def loops(self, target: str) -> list[str]:
        """One line for each rigid edge among the frames joined to ``target`` that closes a
        loop whose chains disagree by more than 1 mm or 1 mrad (tf2 refuses a loop; here
        the chain of fewest links from ``target`` is used)."""
        return [
            f"/tf_static or /tf: frames '{a}' and '{b}' are joined by a transform and by "
            f"another chain that differ by {dist:.3f} m and {np.degrees(angle):.2f} deg (a "
            "loop in the tf tree: a frame published under two parents?); transforms from "
            f"'{frame_name(target)}' take the chain of fewest links"
            for a, b, dist, angle in self._reach(frame_name(target))[1]
        ]

    def _reach(
        self, target: str
    ) -> tuple[dict[str, np.ndarray], list[tuple[str, str, float, float]]]:
        """Breadth-first from ``target``: ``T_target_frame`` of every frame reached, and the
        edges between reached frames that disagree with them (frames, metres, radians)."""
        neighbours: dict[str, list[tuple[str, np.ndarray]]] = {}
        for (parent, child), T in self.rigid.items():
            neighbours.setdefault(parent, []).append((child, T))
            neighbours.setdefault(child, []).append((parent, invert_transform(T)))
        reached = {target: np.eye(4)}
        queue = deque([target])
        tree: set[frozenset[str]] = set()
        loops: dict[frozenset[str], tuple[str, str, float, float]] = {}
        while queue:
            frame = queue.popleft()
            for other, T_frame_other in neighbours.get(frame, []):
                if other not in reached:
                    reached[other] = reached[frame] @ T_frame_other
                    tree.add(frozenset((frame, other)))
                    queue.append(other)
                elif frozenset((frame, other)) not in tree | loops.keys():
                    D = invert_transform(reached[other]) @ reached[frame] @ T_frame_other
                    dist = float(np.linalg.norm(D[:3, 3]))
                    angle = float(np.arccos(np.clip((np.trace(D[:3, :3]) - 1) / 2, -1, 1)))
                    if dist > LOOP_TOL or angle > LOOP_TOL:
                        loops[frozenset((frame, other))] = (frame, other, dist, angle)
        return reached, list(loops.values())

    def require(self, target: str, source: str, where: str) -> np.ndarray:
        """:meth:`lookup`, or a one-line DatasetError naming both frames and ``where``."""
        T = self.lookup(target, source)
        if T is not None:
            return T
        known = self.frames()
        shown = ", ".join(known[:12]) + (" ..." if len(known) > 12 else "")
        why = (
            "connected only through moving /tf transforms"
            if any(frame_name(source) in e for e in self.moving)
            else "no static transform chain"
        )
        hint = ""
        if frame_name(target) not in known:  # e.g. a single lidar's bag without any tf
            hint = (
                f"; '{frame_name(target)}' is in no transform of the bag: choose another base "
                f"frame (--base-frame), such as the sensor's own '{frame_name(source)}'"
            )
        if not self.static_edges:
            hint += (
                "; the bag holds no /tf_static transform (a recording started after the "
                "static transform publishers can miss their latched messages): add them to "
                "the bag"
            )
        if self.ignored:
            hint += "; " + "; ".join(self.ignored_notes()[:3])
        raise DatasetError(
            f"{where}: no transform from frame '{frame_name(source)}' to base frame "
            f"'{frame_name(target)}' in /tf_static or /tf ({why}; frames: {shown or 'none'})" + hint
        )
