"""KITTI's segment errors: the odometry benchmark's translation % and rotation deg/100 m.

The definition of the KITTI devkit (``evaluate_odometry.cpp``): for every first frame
``i`` taken every ``step`` (10) frames and every segment length ``L`` in 100, 200, ...,
800 m, the last frame ``j`` is the first whose distance along the ground truth exceeds the
first frame's by more than ``L``; the error of the segment is
``E = inv(inv(est_i) est_j) @ inv(gt_i) gt_j``, its translation error ``|t_E| / L`` and its
rotation error ``angle(R_E) / L``. The sequence's errors are the means over all segments
(each segment counted once, whatever its length); ``translation_pct`` is that mean x 100
and ``rotation_deg_per_100m`` the mean in rad/m x 180/pi x 100. The devkit evaluates the
camera frame: pass camera-frame poses, or Velodyne-frame poses with ``Tr`` (T_cam0_velo).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from planodom.errors import GeometryError

#: Segment lengths (m) of the benchmark.
SEGMENT_LENGTHS = (100, 200, 300, 400, 500, 600, 700, 800)
#: The devkit's step between first frames.
STEP = 10


def _check(poses: np.ndarray, name: str) -> np.ndarray:
    poses = np.asarray(poses, dtype=np.float64)
    if poses.ndim != 3 or poses.shape[1:] != (4, 4) or not np.all(np.isfinite(poses)):
        raise GeometryError(f"{name} must be finite (E, 4, 4) poses, got shape {poses.shape}")
    return poses


def _rotation_angle(R: np.ndarray) -> float:
    """The devkit's rotation error: ``acos(clip((trace - 1) / 2))``, radians."""
    return math.acos(max(min(0.5 * (float(np.trace(R)) - 1.0), 1.0), -1.0))


def kitti_segment_errors(
    est_poses: np.ndarray,
    gt_poses: np.ndarray,
    Tr: np.ndarray | None = None,
    lengths: tuple[int, ...] = SEGMENT_LENGTHS,
    step: int = STEP,
) -> dict[str, Any]:
    """KITTI's segment errors of an estimate against the ground truth (same E frames).

    Args:
        est_poses, gt_poses: (E, 4, 4) poses of the same frames (any world frames: only
            relative motions count).
        Tr: ``T_cam0_velo`` (4, 4): the poses are Velodyne-frame ``T_world_velo`` and are
            taken to the camera frame (``Tr @ T @ Tr^-1``) first, as the devkit evaluates.
            None: evaluated as given.
        lengths: segment lengths, metres.
        step: frames between segment starts.

    Returns:
        ``translation_pct`` (mean translation error, % of the length),
        ``rotation_deg_per_100m``, ``segments`` (count), ``length_m`` (the ground truth's
        path length) and ``per_length``: ``{L: {translation_pct, rotation_deg_per_100m,
        segments}}`` for the lengths that have segments. Sequences shorter than the
        shortest length give NaN errors, 0 segments and an empty ``per_length``.
    """
    est, gt = _check(est_poses, "est_poses"), _check(gt_poses, "gt_poses")
    if est.shape != gt.shape:
        raise GeometryError(f"est_poses {est.shape} and gt_poses {gt.shape} differ in shape")
    if Tr is not None:
        Tr = np.asarray(Tr, dtype=np.float64)
        Tr_inv = np.linalg.inv(Tr)
        est, gt = Tr @ est @ Tr_inv, Tr @ gt @ Tr_inv
    steps = np.linalg.norm(np.diff(gt[:, :3, 3], axis=0), axis=1)
    dist = np.concatenate([[0.0], np.cumsum(steps)])
    errors: dict[int, list[tuple[float, float]]] = {L: [] for L in lengths}
    est_inv, gt_inv = np.linalg.inv(est), np.linalg.inv(gt)
    for first in range(0, len(gt), step):
        for L in lengths:
            beyond = np.flatnonzero(dist[first:] > dist[first] + L)
            if len(beyond) == 0:
                continue
            last = first + int(beyond[0])
            delta_gt = gt_inv[first] @ gt[last]
            delta_est = est_inv[first] @ est[last]
            E = np.linalg.inv(delta_est) @ delta_gt
            errors[L].append((_rotation_angle(E[:3, :3]) / L, float(np.linalg.norm(E[:3, 3])) / L))
    everything = [e for L in lengths for e in errors[L]]
    return {
        **_summary(everything),
        "length_m": float(dist[-1]),
        "per_length": {L: _summary(errors[L]) for L in lengths if errors[L]},
    }


def _summary(errors: list[tuple[float, float]]) -> dict[str, Any]:
    """Mean errors of ``(rotation rad/m, translation m/m)`` pairs in the benchmark's units."""
    if not errors:
        return {"translation_pct": math.nan, "rotation_deg_per_100m": math.nan, "segments": 0}
    r, t = np.mean(np.array(errors), axis=0)
    return {
        "translation_pct": float(t * 100.0),
        "rotation_deg_per_100m": float(math.degrees(r) * 100.0),
        "segments": len(errors),
    }
