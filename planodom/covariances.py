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
    chained = chained_covariances(
        run.poses, relative, prev, status, config.odometry.refine_max_sigma_m
    )
    return {
        "times": np.asarray(run.times, dtype=np.float64),
        "relative": relative,
        "relative_prev": prev,
        "relative_status": status,
        "chained": chained,
    }


def chained_covariances(
    poses: np.ndarray,
    relative: np.ndarray,
    relative_prev: np.ndarray,
    relative_status: np.ndarray | list[str],
    bridged_sigma_m: float,
    shared: bool = True,
) -> np.ndarray:
    """(E, 6, 6) covariance of each odometry pose, chained from its relative poses.

    ``T_world_k = T_world_p @ S`` (p = ``relative_prev[k]``, ``S = T_p_k``) with errors as
    right perturbations in gtsam's Pose3 tangent [rot, trans] (body frame):
    ``x_k = Ad(S^-1) x_p + w_k``, ``w_k`` the step's error: its (roll, pitch, yaw, x, y)
    covariance taken as (rot, trans) with the translation turned into epoch k's frame, the
    vertical's variance the mean of x's and y's (the odometry does not carry it).

    A step that is not "ok" (degenerate, unresolved) is bridged along the horizontal
    directions its translation did not measure: the eigen-directions of its (x, y) block
    whose sigma exceeds ``bridged_sigma_m`` (``odometry.refine_max_sigma_m``, the bound
    above which the refinement does not measure a direction). There its stated variance is
    the constant-velocity prediction's (velocity sigma times dt, squared), and the steps of
    one run of consecutive bridged steps all carry the same velocity error: with
    ``shared`` (default) that part is one error ``z ~ N(0, I)`` for the run,
    ``w_k = L_k z + u_k``, ``L_k`` the symmetric square root of the bridged part and
    ``u_k`` the rest (independent; the covariance between the two parts is dropped), so a
    run of n equal bridged steps of sigma s along one direction adds (n s)^2, i.e. the
    velocity's variance times the run's elapsed time squared, instead of n s^2. This
    replaces the independent per-step terms rather than adding to them: the stated sigma
    is that velocity error, counted once. The run's term stops growing at the next "ok"
    step (the velocity is measured again) and is carried on from there. ``shared=False``
    chains every step independently.

    Args:
        poses: (E, 4, 4) ``T_world_base``. relative: (E, 5, 5) step covariances (rad^2,
            m^2; row 0 and unknown ones NaN). relative_prev: (E,) reference epochs (-1 for
            the first). relative_status: (E,) "first", "ok", "degenerate", "unresolved".
        bridged_sigma_m: a direction with a larger sigma is bridged, m.

    Returns:
        (E, 6, 6); zero for the first epoch, NaN from a step whose covariance is unknown.
    """
    n = len(poses)
    closed = np.zeros((n, 6, 6))  # per epoch: the covariance without the open run's term
    run = np.zeros((n, 6, 6))  # per epoch: the open run's shared term G (covariance G G^T)
    for k in range(1, n):
        p = int(relative_prev[k])
        p = k - 1 if p < 0 else p
        S = np.linalg.solve(poses[p], poses[k])  # T_p_k
        A = _adjoint(np.linalg.inv(S))
        Q, L = _step_tangent(relative[k]), np.zeros((6, 6))
        if shared and str(relative_status[k]) in ("degenerate", "unresolved"):
            Q, L = _bridged_split(Q, bridged_sigma_m)
        J = np.eye(6)  # the translation from the previous frame into epoch k's
        J[3:, 3:] = S[:3, :3].T
        Q, L = J @ Q @ J.T, J @ L @ J.T
        G = run[p]
        if L.any():  # the run goes on (or starts): one velocity error
            run[k] = A @ G + L
            closed[k] = A @ closed[p] @ A.T + Q
        else:  # measured: the run's term is carried on, no longer shared
            closed[k] = A @ (closed[p] + G @ G.T) @ A.T + Q
    return closed + run @ np.transpose(run, (0, 2, 1))


def _adjoint(T: np.ndarray) -> np.ndarray:
    """(6, 6) adjoint of ``T`` (4, 4) on Pose3's tangent [rot, trans]:
    ``[[R, 0], [t^ R, R]]``."""
    R, t = T[:3, :3], T[:3, 3]
    hat = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
    Ad = np.zeros((6, 6))
    Ad[:3, :3] = Ad[3:, 3:] = R
    Ad[3:, :3] = hat @ R
    return Ad


def _step_tangent(cov5: np.ndarray) -> np.ndarray:
    """(6, 6) a step's (roll, pitch, yaw, x, y) covariance (5, 5) as [rot, trans] in the
    previous frame (z's variance the mean of x's and y's)."""
    Q = np.zeros((6, 6))
    Q[:5, :5] = cov5
    Q[5, 5] = 0.5 * (cov5[3, 3] + cov5[4, 4])
    return Q


def _bridged_split(Q: np.ndarray, sigma_m: float) -> tuple[np.ndarray, np.ndarray]:
    """``Q`` (6, 6) of a bridged step split into its independent part (6, 6) and the
    symmetric square root ``L`` (6, 6) of its part along the translation's horizontal
    eigen-directions with a sigma above ``sigma_m`` (see :func:`chained_covariances`)."""
    if not np.all(np.isfinite(Q)):
        return Q, np.zeros((6, 6))
    lam, V = np.linalg.eigh(Q[3:5, 3:5])
    bridged = lam > sigma_m**2
    Pb = V[:, bridged] @ V[:, bridged].T  # projector on the bridged directions (2, 2)
    M = np.eye(6)
    M[3:5, 3:5] -= Pb
    L = np.zeros((6, 6))
    L[3:5, 3:5] = V[:, bridged] @ np.diag(np.sqrt(lam[bridged])) @ V[:, bridged].T
    return M @ Q @ M.T, L


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
