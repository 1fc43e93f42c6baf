"""Writing a results folder: trajectories (TUM, KITTI), per-epoch CSV, config, metrics.

Layout of ``<out>/``::

    poses.tum          T_world_base per epoch (the first epoch's base frame is the world),
                       at the recording's epoch times (a bag's: seconds since the Unix epoch)
    poses_kitti.txt    the same poses as KITTI rows (3x4 row-major, no time); from a KITTI
                       sequence in KITTI's camera convention (Tr T Tr^-1, as poses/NN.txt)
    epochs.csv         one row per epoch: 5-DoF increments, status, diagnostics
    covariances.npz    per-epoch relative-pose and smoothed covariances
                       (keys and units: :mod:`planodom.covariances`)
    trajectory.png     top view of the estimate over the reference (:mod:`planodom.plots`)
    errors.png         per-epoch 5-DoF errors with ±2σ bands
    planes.png         planes, pair associations and consensus inliers per epoch
    config.yaml        the resolved configuration
    timing.json        the front end's speed (epochs_per_second): measured by the clock, it
                       is the one file that differs between two runs of the same command
    metrics.json       metrics against ground truth, when it is known (with KITTI's
                       segment errors when the reference is 100 m long or more)
    odometry.tum       (smoothing) the raw odometry beside the smoothed poses.tum
    dataset/           (a simulated scenario) the dataset the run read

A folder is written whole or not at all (:func:`results_folder`): into a hidden sibling
renamed into place at the end, never over its inputs, replacing an earlier results folder
only when asked; without a folder given, into ``results/<timestamp>/`` with a ``latest``
link.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from planodom import metrics
from planodom.config import PlanodomConfig
from planodom.datasets import write_tum
from planodom.datasets.kitti import write_kitti_camera_poses
from planodom.metrics_kitti import kitti_segment_errors
from planodom.odometry import OdometryRun, epoch_rows
from planodom.outputs import atomic_folder, link_latest, timestamped_folder

if TYPE_CHECKING:
    from planodom.smoothing.batch import SmoothingResult

__all__ = ["write_tum"]

#: What a results folder may hold: ``--overwrite`` replaces only folders of these.
RESULT_ENTRIES = frozenset(
    {"poses.tum", "poses_kitti.txt", "epochs.csv", "config.yaml", "metrics.json", "timing.json"}
    | {"odometry.tum", "dataset", "covariances.npz"}
    | {"trajectory.png", "errors.png", "planes.png"}
)


@dataclass(frozen=True)
class ResultsFolder:
    """Where a run writes (``tmp``) and where its results end up (``path``)."""

    tmp: Path
    path: Path


@contextlib.contextmanager
def results_folder(
    out: str | Path | None,
    *,
    overwrite: bool = False,
    inputs: Sequence[str | Path] = (),
    root: str | Path = "results",
) -> Iterator[ResultsFolder]:
    """A results folder written whole or not at all (:func:`planodom.outputs.atomic_folder`).

    Args:
        out: the folder; None: a fresh ``root/<timestamp>/``, linked as ``root/latest``.
        overwrite: replace an existing results folder ``out`` (one holding only
            :data:`RESULT_ENTRIES`).
        inputs: the run's input files and folders, which ``out`` may not be, lie in or
            contain.
    """
    path = timestamped_folder(root) if out is None else Path(out)
    owned = _is_result_entry
    with atomic_folder(path, overwrite=overwrite, inputs=inputs, owned=owned) as tmp:
        yield ResultsFolder(tmp, path)
    if out is None:
        link_latest(path)


def _is_result_entry(path: Path) -> bool:
    return path.name in RESULT_ENTRIES


def write_kitti(path: str | Path, poses: np.ndarray) -> None:
    """KITTI odometry format: one line per pose (E, 4, 4), the top 3x4 rows row-major.

    Written with ``repr`` precision so that a round trip is exact (evo's KITTI writer
    rounds through ``%e`` formatting).
    """
    lines = [" ".join(repr(float(v)) for v in T[:3, :4].ravel()) for T in np.asarray(poses)]
    Path(path).write_text("\n".join(lines) + ("\n" if lines else ""))


def write_trajectory(
    out: Path, times: np.ndarray, poses: np.ndarray, Tr: np.ndarray | None = None
) -> None:
    """``poses.tum`` and ``poses_kitti.txt`` of ``poses`` (E, 4, 4) at ``times`` (E,) s.

    With ``Tr`` (4, 4) ``T_cam0_velo`` of a KITTI sequence, ``poses_kitti.txt`` is in
    KITTI's camera convention (:func:`planodom.datasets.kitti.write_kitti_camera_poses`),
    for ``evo_ape kitti`` and the devkit.
    """
    write_tum(out / "poses.tum", times, poses)
    if Tr is None:
        write_kitti(out / "poses_kitti.txt", poses)
    else:
        write_kitti_camera_poses(out / "poses_kitti.txt", poses, Tr)


def kitti_metrics(
    poses: np.ndarray, gt_poses: np.ndarray | None, Tr: np.ndarray | None = None
) -> dict[str, float]:
    """KITTI's segment errors (:func:`planodom.metrics_kitti.kitti_segment_errors`) as
    ``kitti_translation_pct``, ``kitti_rotation_deg_per_100m`` and ``kitti_segments``;
    empty without ground truth or when it is shorter than the shortest segment (100 m)."""
    poses, gt_poses = referenced(poses, gt_poses)
    if gt_poses is None or len(poses) < 2:
        return {}
    seg = kitti_segment_errors(poses, gt_poses, Tr)
    if seg["segments"] == 0:
        return {}
    return {
        "kitti_translation_pct": float(seg["translation_pct"]),
        "kitti_rotation_deg_per_100m": float(seg["rotation_deg_per_100m"]),
        "kitti_segments": float(seg["segments"]),
    }


def write_rows(path: str | Path, rows: Sequence[Mapping[str, object]]) -> None:
    """A CSV with the union of the rows' keys as columns (first-seen order)."""
    columns: list[str] = []
    for row in rows:
        columns += [k for k in row if k not in columns]
    with Path(path).open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)


def _json_safe(value: object) -> object:
    if isinstance(value, Mapping):
        return {str(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


#: Metrics measured by the clock, written to ``timing.json`` (at any depth of the
#: metrics), so that ``metrics.json`` is the same bytes for the same command and input.
TIMING_KEYS = frozenset({"epochs_per_second"})


def _split_timing(metrics: Mapping[str, object]) -> tuple[dict, dict]:
    """``metrics`` without, and only with, the :data:`TIMING_KEYS` (nesting kept)."""
    rest: dict = {}
    timing: dict = {}
    for key, value in metrics.items():
        if key in TIMING_KEYS:
            timing[key] = value
        elif isinstance(value, Mapping):
            rest[key], inner = _split_timing(value)
            if inner:
                timing[key] = inner
        else:
            rest[key] = value
    return rest, timing


def write_metrics(out: Path, metrics: Mapping[str, object]) -> None:
    """``metrics.json`` (NaN and inf written as null); clock measurements
    (:data:`TIMING_KEYS`) go to ``timing.json`` instead."""
    rest, timing = _split_timing(metrics)
    (out / "metrics.json").write_text(json.dumps(_json_safe(rest), indent=2) + "\n")
    if timing:
        (out / "timing.json").write_text(json.dumps(_json_safe(timing), indent=2) + "\n")


def trajectory_metrics(poses: np.ndarray, gt_poses: np.ndarray | None) -> dict[str, float]:
    """ATE / RPE / drift / per-epoch errors, plus horizontal ATE and drift (``_xy``).

    The odometry observes 5 DoF, so z is only known where the planes constrain it; the
    horizontal figures are the ones to compare. Empty without ground truth. Over the epochs
    with a reference pose (:func:`referenced`): when some have none, ``epochs`` counts all
    and ``evaluated_epochs`` those, and no RPE or per-epoch error pairs two epochs across a
    gap (:func:`planodom.metrics.rpe`).
    """
    epochs = len(poses)
    index = None
    if gt_poses is not None and len(gt_poses) == epochs:
        index = np.flatnonzero(np.all(np.isfinite(gt_poses), axis=(1, 2)))
    poses, gt_poses = referenced(poses, gt_poses)
    if gt_poses is None or len(poses) < 2:
        return {}
    if index is not None and len(index) == epochs:
        index = None  # every epoch has a reference: the poses are consecutive
    out = metrics.summarize(poses, gt_poses, index=index)
    flat = metrics.summarize(poses, gt_poses, xy_only=True, index=index)
    out |= {f"{k}_xy": flat[k] for k in ("ate_rmse_m", "drift_m", "drift_percent")}
    if len(poses) < epochs:
        out = {"epochs": float(epochs), "evaluated_epochs": out.pop("epochs")} | out
    return out


def smoothing_metrics(
    result: SmoothingResult, gt_poses: np.ndarray | None, Tr: np.ndarray | None = None
) -> dict[str, Any]:
    """A smoothing run's :func:`trajectory_metrics` and :func:`kitti_metrics` (with ground
    truth), and under ``smoother`` what the smoother counted
    (:func:`planodom.smoothing.diagnostics.smoother_metrics`: the graph, the fixed-lag
    smoother's QR fallbacks and split indefinite marginals, loop closure's verdicts)."""
    from planodom.smoothing.diagnostics import smoother_metrics

    out: dict[str, Any] = trajectory_metrics(result.poses, gt_poses)
    out |= kitti_metrics(result.poses, gt_poses, Tr)
    return out | {"smoother": smoother_metrics(result)}


def referenced(
    poses: np.ndarray, gt_poses: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray | None]:
    """``poses`` (E, 4, 4) and ``gt_poses`` at the epochs with a reference pose: a bag's
    reference that spans only part of the run is NaN at the others
    (:class:`planodom.datasets.rosbag.BagDataset`); the whole arrays when none is NaN."""
    if gt_poses is None:
        return poses, None
    known = np.all(np.isfinite(gt_poses), axis=(1, 2))
    if known.all():
        return poses, gt_poses
    return np.asarray(poses)[known], np.asarray(gt_poses)[known]


def odometry_metrics(run: OdometryRun, gt_poses: np.ndarray | None) -> dict[str, float]:
    """Run statistics, and :func:`trajectory_metrics` when ``gt_poses`` is known."""
    statuses = run.statuses
    seconds = sum(run.seconds.values())
    out: dict[str, float] = {
        "epochs": float(len(statuses)),
        "unresolved_epochs": float(run.n_unresolved),
        "degenerate_epochs": float(run.n_degenerate),
        "planes_per_epoch_median": float(np.median(run.n_planes)) if len(run.n_planes) else 0.0,
        "epochs_per_second": len(statuses) / seconds if seconds > 0 else float("nan"),
    }
    return out | trajectory_metrics(run.poses, gt_poses)


def write_odometry_run(
    out: Path, run: OdometryRun, metrics: Mapping[str, object], Tr: np.ndarray | None = None
) -> None:
    """Write the trajectory, epoch rows, config and ``metrics`` of an odometry run to
    ``out`` (``metrics``: :func:`odometry_metrics`, plus whatever the caller adds; ``Tr``:
    see :func:`write_trajectory`)."""
    write_trajectory(out, run.times, run.poses, Tr)
    write_rows(out / "epochs.csv", epoch_rows(run))
    if run.config is not None:
        write_config(out, run.config)
    write_metrics(out, metrics)


def write_config(out: Path, config: PlanodomConfig) -> None:
    """``config.yaml``: the resolved configuration of the run."""
    config.to_yaml(out / "config.yaml")
