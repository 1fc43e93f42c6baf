"""Point-based peers on the same scans: KISS-ICP (optional) and open3d's point-to-plane ICP.

Both return poses ``T_world_base`` (E, 4, 4) from identity at the epochs' reference times
and the seconds they took. KISS-ICP is installed with ``uv sync --extra baselines``
(``kiss_available()`` says whether it is); it deskews to the last point of a frame (its
timestamps normalised over the frame), so its poses are carried back to the reference
time with its own constant-velocity increment.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from planodom._open3d import o3d
from planodom.geometry import invert_transform, se3_exp, se3_log
from planodom.scan import Scan


def kiss_available() -> bool:
    """Whether the optional peer ``kiss_icp`` is installed."""
    try:
        import kiss_icp  # noqa: F401
    except ImportError:
        return False
    return True


def kiss_icp_poses(
    scans: Sequence[Scan], epoch_period_s: float, max_range_m: float = 100.0
) -> tuple[np.ndarray, float]:
    """KISS-ICP (defaults: voxel size ``max_range_m / 100``, adaptive threshold, deskewing
    when the scans have times) over ``scans``; poses at the reference times and seconds."""
    from kiss_icp.config import KISSConfig
    from kiss_icp.kiss_icp import KissICP

    config = KISSConfig()
    config.data.max_range = float(max_range_m)
    config.mapping.voxel_size = float(max_range_m) / 100.0
    config.registration.max_num_threads = 1
    deskew = all(s.t is not None and len(s) and np.ptp(s.t) > 0 for s in scans)
    config.data.deskew = deskew
    odo = KissICP(config)
    poses, ends = [], []
    c0 = time.perf_counter()
    for scan in scans:
        stamps = scan.t if deskew and scan.t is not None else np.zeros(len(scan))
        odo.register_frame(np.ascontiguousarray(scan.points), np.asarray(stamps, dtype=np.float64))
        poses.append(odo.last_pose.copy())
        ends.append(float(np.max(stamps)) if len(stamps) else 0.0)
    seconds = time.perf_counter() - c0
    P = np.array(poses)
    if deskew and len(P) > 1:  # poses refer to each frame's last point: back to t = 0
        steps = invert_transform(P[:-1]) @ P[1:]
        twists = se3_log(np.concatenate([steps[:1], steps])) / epoch_period_s
        P = P @ se3_exp(-np.array(ends)[:, None] * twists)
    return invert_transform(P[0])[None] @ P, seconds


def _cloud(points: np.ndarray, voxel: float, radius: float):
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    pcd = pcd.voxel_down_sample(voxel)
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=radius, max_nn=20))
    return pcd


def open3d_icp_poses(
    scans: Sequence[Scan], voxel_m: float = 0.2, max_distance_m: float = 1.0
) -> tuple[np.ndarray, float]:
    """Frame-to-frame point-to-plane ICP (open3d ``registration_icp``) from the
    constant-velocity prediction, on voxel-downsampled points (normals from 20
    neighbours within 5 voxels); no deskewing. Poses and seconds."""
    reg = o3d.pipelines.registration
    method = reg.TransformationEstimationPointToPlane()
    criteria = reg.ICPConvergenceCriteria(max_iteration=30)
    poses, step = [np.eye(4)], np.eye(4)
    c0 = time.perf_counter()
    prev = _cloud(scans[0].points, voxel_m, 5 * voxel_m)
    for scan in scans[1:]:
        curr = _cloud(scan.points, voxel_m, 5 * voxel_m)
        if len(curr.points) >= 10 and len(prev.points) >= 10:
            fit = reg.registration_icp(curr, prev, max_distance_m, step, method, criteria)
            step = np.asarray(fit.transformation)
        poses.append(poses[-1] @ step)
        prev = curr
    return np.array(poses), time.perf_counter() - c0
