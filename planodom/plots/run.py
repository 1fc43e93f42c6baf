"""The pictures of a results folder: ``run`` / ``smooth`` (three) and ``eval`` (two)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from planodom.geometry import invert_transform
from planodom.metrics import (
    POSE5_NAMES,
    Alignment,
    aligned,
    per_epoch_errors,
    relative_motions,
)
from planodom.odometry import OdometryRun, epoch_rows
from planodom.plots.errors import plot_errors
from planodom.plots.planes import plot_planes
from planodom.plots.trajectory import plot_trajectory

#: The pictures' file names.
TRAJECTORY_PNG, ERRORS_PNG, PLANES_PNG = "trajectory.png", "errors.png", "planes.png"


def odometry_sigmas(run: OdometryRun) -> np.ndarray:
    """(E-1, 5) standard deviations of the increments of epochs 1..E-1 (NaN: unknown)."""
    return np.array([r.sigmas5 if r is not None else np.full(5, np.nan) for r in run.results[1:]])


def increment_errors(est: np.ndarray, gt: np.ndarray) -> dict[str, np.ndarray]:
    """Signed 5-DoF errors (E-1,) of the increments of ``est`` against ``gt`` (E, 4, 4)."""
    return per_epoch_errors(relative_motions(est), relative_motions(gt))


def _origin_aligned(est: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """The estimate (E, 4, 4) on the reference (E, 4, 4) at its first epoch with a reference
    pose (:func:`~planodom.metrics.aligned` "origin" when every epoch has one; NaN rows of a
    reference that spans part of the run, :func:`planodom.results.referenced`)."""
    known = np.flatnonzero(np.all(np.isfinite(gt), axis=(1, 2)))
    if len(known) == len(gt):
        return aligned(est, gt, "origin")
    k = known[0]
    return gt[k] @ invert_transform(est[k]) @ est


def _increment_errors(est: np.ndarray, gt: np.ndarray) -> dict[str, np.ndarray]:
    """:func:`increment_errors`, NaN at the increments from or to an epoch without a
    reference pose (NaN in ``gt``)."""
    known = np.all(np.isfinite(gt), axis=(1, 2))
    if known.all():
        return increment_errors(est, gt)
    both = known[:-1] & known[1:]
    out = {name: np.full(len(est) - 1, np.nan) for name in POSE5_NAMES}
    if both.any():
        rel_gt = invert_transform(gt[:-1][both]) @ gt[1:][both]
        for name, e in per_epoch_errors(relative_motions(est)[both], rel_gt).items():
            out[name][both] = e
    return out


def _gap_breaks(poses: np.ndarray, index: np.ndarray | None) -> np.ndarray:
    """``poses`` (M, 4, 4) with a NaN pose between two whose ``index`` (M,) numbers are
    not consecutive: a line drawn through them breaks at the gap (None: as given)."""
    if index is None:
        return poses
    cuts = np.flatnonzero(np.diff(np.asarray(index)) != 1) + 1
    return np.insert(poses, cuts, np.nan, axis=0)


def _reference_track(gt: np.ndarray) -> np.ndarray:
    """The reference (E, 4, 4) to draw: from its first to its last epoch with a pose, NaN
    (a break in the line, not a chord) at the epochs in a gap."""
    known = np.flatnonzero(np.all(np.isfinite(gt), axis=(1, 2)))
    return gt[known[0] : known[-1] + 1] if len(known) else gt[:0]


def write_run_plots(
    out: str | Path,
    odometry: OdometryRun,
    gt_poses: np.ndarray | None,
    smoothed: np.ndarray | None = None,
    name: str = "planodom run",
) -> list[Path]:
    """``trajectory.png``, ``errors.png`` and ``planes.png`` of an odometry run (and, with
    ``smoothed`` (E, 4, 4), of its smoothing: drawn as the estimate, the odometry beside
    it) into ``out``. Without ``gt_poses`` the trajectory stands alone and the errors
    panel shows the ±2σ bands of the odometry's covariances."""
    out = Path(out)
    best = odometry.poses if smoothed is None else smoothed
    # the estimate first (blue in both pictures), the odometry beside the smoothed (orange)
    tracks = ({} if smoothed is None else {"smoothed": smoothed}) | {"odometry": odometry.poses}
    errors: dict[str, dict[str, np.ndarray]] = {}
    shown = dict(tracks)
    if gt_poses is not None and len(best) > 1:
        shown = {k: _origin_aligned(v, gt_poses) for k, v in tracks.items()}
        errors = {k: _increment_errors(v, gt_poses) for k, v in tracks.items()}
        gt_poses = _reference_track(gt_poses)
    label = "odometry" if smoothed is None else "smoothed"
    others = [("odometry", shown["odometry"])] if smoothed is not None else []
    files = [
        plot_trajectory(
            out / TRAJECTORY_PNG,
            shown[label],
            gt_poses,
            statuses=odometry.statuses,
            others=others,
            title=f"{name}: top view",
            label=label,
        ),  # fmt: skip
        plot_errors(
            out / ERRORS_PNG,
            odometry.times[1:],
            errors,
            odometry_sigmas(odometry),
            title=f"{name}: per-epoch increment errors (estimate - reference)",
        ),  # fmt: skip
        plot_planes(out / PLANES_PNG, epoch_rows(odometry), title=f"{name}: planes per epoch"),
    ]
    return files


def write_eval_plots(
    out: str | Path,
    times: np.ndarray,
    estimate: np.ndarray,
    reference: np.ndarray,
    align: Alignment = "origin",
    name: str = "planodom eval",
    index: np.ndarray | None = None,
) -> list[Path]:
    """``trajectory.png`` and ``errors.png`` of two associated trajectories (E, 4, 4) at
    ``times`` (E,) seconds, the estimate aligned by ``align``. ``index`` (E,): the poses'
    numbers in the estimate when some have no reference pose
    (:func:`planodom.evaluation.associate_indexed`): the lines break across a gap, and
    the increment across it (no increment of the estimate) is not drawn."""
    out = Path(out)
    shown = aligned(estimate, reference, align)
    errors = {"estimate": increment_errors(estimate, reference)} if len(times) > 1 else {}
    if errors and index is not None:
        across = np.diff(np.asarray(index)) != 1
        errors = {
            "estimate": {k: np.where(across, np.nan, e) for k, e in errors["estimate"].items()}
        }
    return [
        plot_trajectory(
            out / TRAJECTORY_PNG,
            _gap_breaks(shown, index),
            _gap_breaks(reference, index),
            title=f"{name}: top view ({align})",
        ),
        plot_errors(
            out / ERRORS_PNG, times[1:], errors, title=f"{name}: per-epoch increment errors"
        ),
    ]
