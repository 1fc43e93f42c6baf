"""``covariances.npz``: the uncertainty of a run, kept beside its trajectories.

Keys (numpy arrays; E epochs; NaN where a value is unknown):

- ``times`` (E,) float64: epoch reference times, seconds (as in ``poses.tum``).
- ``relative`` (E, 5, 5) float64: covariance of the odometry's relative pose of epoch k
  from its reference epoch, in (roll, pitch, yaw, x, y) of ``T_prev_curr``: rad^2, rad m
  and m^2 (:attr:`planodom.odometry.RelativePose.covariance`). Row 0 (the first epoch)
  is NaN. DoF a relative pose did not measure (degenerate, unresolved) hold the squared
  motion bound.
- ``relative_prev`` (E,) int64: the reference epoch of each relative pose (k - 1 unless
  the odometry skipped an epoch; -1 for the first).
- ``relative_status`` (E,) str: "first", "ok", "degenerate" or "unresolved".
- ``smoothed_batch`` / ``smoothed_windowed`` (E, 6, 6) float64, after ``planodom smooth``:
  marginal covariance of each smoothed pose ``T_world_base`` in gtsam's Pose3 tangent
  ``[rot (rad), trans (m)]``, right perturbation (body frame). Batch: relative to the
  first pose (see :func:`planodom.smoothing.marginals.pose_covariances`); fixed-lag: as the
  pose left the window (see :class:`planodom.smoothing.WindowedSmoother`).

Stored without pickling: ``np.load(path)`` reads it.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from planodom.errors import DatasetError
from planodom.odometry import OdometryRun

FILE = "covariances.npz"


def odometry_covariances(run: OdometryRun) -> dict[str, np.ndarray]:
    """``times``, ``relative``, ``relative_prev`` and ``relative_status`` of a run."""
    n = len(run.results)
    relative = np.full((n, 5, 5), np.nan)
    prev = np.full(n, -1, dtype=np.int64)
    for k, r in enumerate(run.results):
        if r is None:
            continue
        prev[k] = r.prev if r.prev >= 0 else k - 1
        if r.covariance is not None:
            relative[k] = r.covariance
    return {
        "times": np.asarray(run.times, dtype=np.float64),
        "relative": relative,
        "relative_prev": prev,
        "relative_status": np.array(run.statuses, dtype="<U10"),
    }


def write_covariances(path: str | Path, arrays: Mapping[str, np.ndarray | None]) -> None:
    """Write ``arrays`` (None values left out) to ``path`` (an ``.npz``, uncompressed)."""
    kept = {k: np.asarray(v) for k, v in arrays.items() if v is not None}
    with Path(path).open("wb") as fh:
        np.savez(fh, **kept)  # type: ignore[arg-type]


def read_covariances(path: str | Path) -> dict[str, np.ndarray]:
    """The arrays of a ``covariances.npz`` (see the module docstring).

    Raises:
        DatasetError: naming the file when it is not an npz archive of plain arrays.
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except (OSError, ValueError) as exc:
        raise DatasetError(f"{path}: not a covariances archive ({exc})") from None
