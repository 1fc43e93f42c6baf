"""Evaluating a trajectory file against a reference: reading TUM or KITTI files,
associating their timestamps, and the metrics (``planodom eval``).

A TUM file (``time tx ty tz qx qy qz qw``) carries times; a KITTI file (12 numbers per
line, no times) is paired by index. Two TUM trajectories need not share timestamps: each
estimated pose is matched to the reference pose nearest in time within ``max_diff``
seconds (evo's ``sync.associate_trajectories``), after shifting the estimate's times by
``offset`` seconds; poses without a partner are left out.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from evo.core import sync
from evo.core.trajectory import PoseTrajectory3D

from planodom import metrics
from planodom.datasets.kitti import read_kitti_poses
from planodom.datasets.tum import read_tum
from planodom.errors import DatasetError
from planodom.metrics_kitti import kitti_segment_errors


@dataclass(frozen=True)
class Trajectory:
    """Poses (E, 4, 4) ``T_world_base`` read from ``path``, at ``times`` (E,) seconds
    (None for a KITTI file, which has no times)."""

    path: Path
    poses: np.ndarray
    times: np.ndarray | None


def read_trajectory(path: str | Path) -> Trajectory:
    """A TUM (8 numbers per line) or KITTI (12) trajectory file, told apart by its first
    data line; a directory is a dataset and its ``poses.tum`` is read.

    Raises:
        DatasetError: naming the file (and line) when it is neither (or a ROS bag).
    """
    path = Path(path)
    bag_names = (".bag", ".db3", ".mcap", ".db3.zstd", ".mcap.zstd")
    if path.name.endswith(bag_names) or (path / "metadata.yaml").is_file():
        raise DatasetError(
            f"{path} is a ROS bag: eval reads TUM or KITTI trajectory files; `planodom "
            "convert BAG OUT --gt-topic TOPIC` writes a bag's reference to OUT/poses.tum"
        )
    if path.is_dir():
        path = path / "poses.tum"
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except OSError as exc:
        raise DatasetError(f"{path}: cannot read trajectory ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise DatasetError(f"{path}: not a trajectory file (not UTF-8 text)") from None
    data = [x.strip() for x in lines if x.strip() and not x.startswith("#")]
    first = data[0].split() if data else []
    if len(first) == 12:
        return Trajectory(path, read_kitti_poses(path), None)
    if len(first) == 8:
        times, poses = read_tum(path)
        return Trajectory(path, poses, times)
    raise DatasetError(f"{path}: {_not_tum_or_kitti(lines[0] if lines else '', data)}")


def _not_tum_or_kitti(head: str, data: list[str]) -> str:
    """Why a file with ``data`` lines (its first line ``head``) is no TUM or KITTI file:
    a CSV export, a EuRoC ground truth, no poses, or another count of fields."""
    if not data:
        return "no poses in the trajectory file (only blank or '#' comment lines)"
    if "," not in data[0]:
        return (
            "not a TUM (8 numbers per line) or KITTI (12 numbers) trajectory; the first "
            f"line has {len(data[0].split())} fields"
        )
    fields = len(data[0].split(","))
    if "p_rs_r" in head.lower() or fields == 17:  # EuRoC's / ASL's ground-truth CSV
        return (
            "a EuRoC ground-truth CSV (times in ns, quaternions qw qx qy qz): eval reads "
            "TUM or KITTI files; `evo_traj euroc FILE --save_as_tum` writes it as TUM"
        )
    return (
        f"values separated by commas ({fields} per line, a CSV export?): a TUM file "
        "separates 'time tx ty tz qx qy qz qw' by spaces, a KITTI file its 12 numbers "
        "(check the quaternion's order, qx qy qz qw, when converting)"
    )


def associate(
    est: Trajectory, ref: Trajectory, max_diff: float = 0.01, offset: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(times (M,), est poses (M, 4, 4), ref poses (M, 4, 4))`` of the matched pairs
    (:func:`associate_indexed` without the index)."""
    return associate_indexed(est, ref, max_diff, offset)[:3]


def associate_indexed(
    est: Trajectory, ref: Trajectory, max_diff: float = 0.01, offset: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(times (M,), est poses (M, 4, 4), ref poses (M, 4, 4), index (M,))`` of the
    matched pairs, ``index`` the estimated poses' numbers in ``est`` (increasing).

    TUM with TUM: nearest reference time within ``max_diff`` s of each estimated time plus
    ``offset`` (the times returned are the reference's). With a KITTI file: by index, the
    counts must agree (times: the TUM file's, else the index x 0.1 s).

    Raises:
        DatasetError: naming the files when no pose can be matched or counts differ.
    """
    if est.times is None or ref.times is None:
        if len(est.poses) != len(ref.poses):
            raise DatasetError(
                f"{est.path}: {len(est.poses)} poses for the {len(ref.poses)} of {ref.path}; "
                "a KITTI file has no times, so both must have the same count"
            )
        times = next((t for t in (ref.times, est.times) if t is not None), None)
        times = np.arange(len(ref.poses)) * 0.1 if times is None else times
        return times, est.poses, ref.poses, np.arange(len(est.poses))
    traj_ref = PoseTrajectory3D(poses_se3=list(ref.poses), timestamps=ref.times)
    traj_est = PoseTrajectory3D(poses_se3=list(est.poses), timestamps=est.times)
    try:
        traj_ref, traj_est = sync.associate_trajectories(
            traj_ref, traj_est, max_diff=max_diff, offset_2=offset
        )
    except sync.SyncException:
        span = f"{est.times[0]:.3f}..{est.times[-1]:.3f} s"
        raise DatasetError(
            f"{est.path}: no pose within {max_diff:g} s of a pose of {ref.path} "
            f"(estimate {span}, reference {ref.times[0]:.3f}..{ref.times[-1]:.3f} s); "
            "see --max-diff and --offset"
        ) from None
    # evo keeps each trajectory's own stamps: the matched estimated poses are found by theirs
    index = np.searchsorted(est.times, traj_est.timestamps)
    return (
        np.asarray(traj_ref.timestamps),
        np.array(traj_est.poses_se3),
        np.array(traj_ref.poses_se3),
        index,
    )


def evaluate(
    est_poses: np.ndarray,
    ref_poses: np.ndarray,
    align: metrics.Alignment = "origin",
    delta: int = 1,
    index: np.ndarray | None = None,
) -> dict[str, float]:
    """:func:`planodom.metrics.summarize` of associated poses (M, 4, 4), with the
    horizontal ATE / drift (``_xy``) and, over 100 m or more, KITTI's segment errors.
    ``index`` (M,): the estimated poses' numbers in their file when some have no reference
    pose (:func:`associate`): no RPE or per-epoch error pairs two poses across a gap (the
    drift's distance takes the reference's straight line across it, :func:`metrics.drift`)."""
    out = metrics.summarize(est_poses, ref_poses, align=align, delta=delta, index=index)
    flat = metrics.summarize(
        est_poses, ref_poses, align=align, delta=delta, xy_only=True, index=index
    )
    out |= {f"{k}_xy": flat[k] for k in ("ate_rmse_m", "drift_m", "drift_percent")}
    seg = kitti_segment_errors(est_poses, ref_poses)
    if seg["segments"]:
        out["kitti_translation_pct"] = float(seg["translation_pct"])
        out["kitti_rotation_deg_per_100m"] = float(seg["rotation_deg_per_100m"])
    return out
