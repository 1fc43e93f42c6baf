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
- ``chained`` (E, 6, 6) float64: covariance of each odometry pose ``T_world_base``
  chained from ``relative`` (:func:`chained_covariances`), in gtsam's Pose3 tangent
  ``[rot (rad), trans (m)]``, right perturbation (body frame), relative to the first pose
  (zero there); a run of bridged steps shares one velocity error. NaN after a step whose
  covariance is unknown.
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
from typing import Literal

import gtsam
import numpy as np

from planodom.config import PlanodomConfig
from planodom.errors import DatasetError
from planodom.odometry import OdometryRun

FILE = "covariances.npz"


def odometry_covariances(run: OdometryRun) -> dict[str, np.ndarray]:
    """``times``, ``relative``, ``relative_prev``, ``relative_status`` and ``chained`` of
    a run (``chained`` with the run's ``odometry.refine_max_sigma_m``, the default's
    without a config)."""
    n = len(run.results)
    relative = np.full((n, 5, 5), np.nan)
    prev = np.full(n, -1, dtype=np.int64)
    for k, r in enumerate(run.results):
        if r is None:
            continue
        prev[k] = r.prev if r.prev >= 0 else k - 1
        if r.covariance is not None:
            relative[k] = r.covariance
    status = np.array(run.statuses, dtype="<U10")
    config = run.config if run.config is not None else PlanodomConfig()
    sigma = config.odometry.refine_max_sigma_m
    chained = chained_covariances(run.poses, run.times, relative, prev, status, sigma)
    return {
        "times": np.asarray(run.times, dtype=np.float64),
        "relative": relative,
        "relative_prev": prev,
        "relative_status": status,
        "chained": chained,
    }


def chained_covariances(
    poses: np.ndarray,
    times: np.ndarray,
    relative: np.ndarray,
    relative_prev: np.ndarray,
    relative_status: np.ndarray | list[str],
    bridged_sigma_m: float,
    velocity: Literal["measured", "stated", "none"] = "measured",
) -> np.ndarray:
    """(E, 6, 6) covariance of each odometry pose, chained from its relative poses.

    ``T_world_k = T_world_p @ S`` (p = ``relative_prev[k]``, ``S = T_p_k``) with errors as
    right perturbations in gtsam's Pose3 tangent [rot, trans] (body frame):
    ``x_k = Ad(S^-1) x_p + w_k``, ``w_k`` the step's error: its (roll, pitch, yaw, x, y)
    covariance taken as (rot, trans) with the translation turned into epoch k's frame, the
    vertical's variance the mean of x's and y's (the odometry does not carry it).

    A step that is not "ok" (degenerate, unresolved) is bridged by constant velocity along
    the horizontal directions its translation did not measure: the eigen-directions of its
    (x, y) block with a sigma above ``bridged_sigma_m`` (``odometry.refine_max_sigma_m``,
    above which the refinement does not measure a direction). The steps of one run of
    consecutive bridged steps share one velocity error e: ``w_k = P_k e dt_k + u_k``
    (``P_k`` the projector on step k's bridged directions), so the run adds e's variance
    times its elapsed time squared along them, where independent terms add n per-step
    variances. ``velocity`` says what e is:

    - ``"measured"`` (default): the error of the velocity the bridge carries, the last
      "ok" step's translation over its interval (its covariance over dt^2, turned with
      the body); on top of the bridged steps' own terms ``u_k`` (their stated variance:
      what the prediction misses in one epoch, independent from step to step);
    - ``"stated"``: the bridged steps' stated variance taken as the velocity error itself,
      instead of independent terms (shared root: its symmetric square root); measured far
      too large (see docs/RESULTS.md);
    - ``"none"``: every step independent.

    The run's term stops growing at the next "ok" step and is carried on from there.

    Args:
        poses: (E, 4, 4) ``T_world_base``. times: (E,) s. relative: (E, 5, 5) step
            covariances (rad^2, m^2; row 0 and unknown ones NaN). relative_prev: (E,)
            reference epochs (-1 for the first). relative_status: (E,) "first", "ok",
            "degenerate", "unresolved".
        bridged_sigma_m: a direction with a larger sigma is bridged, m.

    Returns:
        (E, 6, 6); zero for the first epoch, NaN from a step whose covariance is unknown.
    """
    n = len(poses)
    closed = np.zeros((n, 6, 6))  # per epoch: the covariance without the open run's term
    run = np.zeros((n, 6, 6))  # per epoch: the open run's shared term G (covariance G G^T)
    root = np.zeros((n, 2, 2))  # per epoch: B, the carried velocity's error B z, body frame
    for k in range(1, n):
        p = int(relative_prev[k])
        p = k - 1 if p < 0 else p
        S = np.linalg.solve(poses[p], poses[k])  # T_p_k
        A = gtsam.Pose3(S).inverse().AdjointMap()  # Ad(S^-1)
        Q, L = _step_tangent(relative[k]), np.zeros((6, 6))  # L: the shared part's root
        dt, R2 = float(times[k] - times[p]), S[:2, :2]
        bridged = str(relative_status[k]) in ("degenerate", "unresolved")
        if bridged and velocity != "none" and np.all(np.isfinite(Q)):
            Q, L = _shared(Q, bridged_sigma_m, velocity == "stated", dt * root[p])
        J = np.eye(6)  # the translation from the previous frame into epoch k's
        J[3:, 3:] = S[:3, :3].T
        Q, L = J @ Q @ J.T, J @ L @ J.T
        G = run[p]
        if bridged:  # the run goes on (or starts): one velocity error
            run[k] = A @ G + L
            closed[k] = A @ closed[p] @ A.T + Q
            root[k] = R2.T @ root[p]
        else:  # measured: the run's term is carried on, no longer shared
            closed[k] = A @ (closed[p] + G @ G.T) @ A.T + Q
            if dt > 0 and np.all(np.isfinite(relative[k])):
                lam, V = np.linalg.eigh(relative[k, 3:, 3:])
                root[k] = R2.T @ V @ np.diag(np.sqrt(np.clip(lam, 0, None))) @ V.T / dt
    return closed + run @ np.transpose(run, (0, 2, 1))


def _shared(
    Q: np.ndarray, sigma_m: float, stated: bool, velocity_root: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A bridged step's independent covariance (6, 6) and the root ``L`` (6, 6) of its
    shared part along its bridged directions (``Q``'s horizontal eigen-directions with a
    sigma above ``sigma_m``): ``stated``: the symmetric root of ``Q`` there, taken out of
    ``Q``; else ``velocity_root`` (2, 2, the carried velocity's error root times dt)
    projected on them, ``Q`` kept."""
    lam, V = np.linalg.eigh(Q[3:5, 3:5])
    Vb = V[:, lam > sigma_m**2]
    Pb = Vb @ Vb.T  # projector on the bridged directions (2, 2)
    L = np.zeros((6, 6))
    if not stated:
        L[3:5, 3:5] = Pb @ velocity_root
        return Q, L
    M = np.eye(6)
    M[3:5, 3:5] -= Pb
    L[3:5, 3:5] = Vb @ np.diag(np.sqrt(lam[lam > sigma_m**2])) @ Vb.T
    return M @ Q @ M.T, L


def _step_tangent(cov5: np.ndarray) -> np.ndarray:
    """(6, 6) a step's (roll, pitch, yaw, x, y) covariance (5, 5) as [rot, trans] in the
    previous frame (z's variance the mean of x's and y's)."""
    Q = np.zeros((6, 6))
    Q[:5, :5] = cov5
    Q[5, 5] = 0.5 * (cov5[3, 3] + cov5[4, 4])
    return Q


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
