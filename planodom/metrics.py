"""Trajectory metrics: ATE and RPE through evo, drift, per-epoch 5-DoF increment errors, NEES.

Trajectories are (E, 4, 4) arrays of ``T_world_base`` at the same E epochs (so no time
synchronisation is needed). An odometry estimate starts at identity: its frame is the base
frame of the first epoch; the ground truth is in its own world frame. The two are compared
after ``align`` (see :func:`ate`). Units: metres, and degrees where a key or docstring says
so; per-epoch errors are in radians and metres.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import gtsam
import numpy as np
from evo.core import metrics as evo_metrics
from evo.core.geometry import GeometryException
from evo.core.trajectory import PoseTrajectory3D

from planodom.errors import GeometryError
from planodom.geometry import invert_transform, pose5_from_transform

Alignment = Literal["none", "origin", "se3", "4dof"]
#: Statistics reported for ATE and RPE.
STATISTICS = ("rmse", "mean", "median", "max")
#: The 5 observed degrees of freedom of an increment, in pose5 order.
POSE5_NAMES = ("roll", "pitch", "yaw", "x", "y")


def relative_to_first(poses: np.ndarray) -> np.ndarray:
    """Poses (E, 4, 4) expressed in the frame of the first one: ``inv(T_0) @ T_k``."""
    poses = _check_poses(poses, "poses")
    return invert_transform(poses[0])[None] @ poses


def relative_motions(poses: np.ndarray) -> np.ndarray:
    """Increments (E-1, 4, 4) ``T_k_k+1 = inv(T_k) @ T_k+1`` of poses (E, 4, 4)."""
    poses = _check_poses(poses, "poses")
    return invert_transform(poses[:-1]) @ poses[1:]


def aligned(est_poses: np.ndarray, gt_poses: np.ndarray, align: Alignment = "origin") -> np.ndarray:
    """The estimate (E, 4, 4) expressed in the ground truth's world frame by ``align``.

    - ``"none"``: as given (both must already share a frame).
    - ``"origin"``: ``gt[0] @ inv(est[0]) @ est`` (evo's ``align_origin``): the first poses
      coincide. Position errors are the same as comparing ``est`` with
      :func:`relative_to_first` of the ground truth, but stay in the world frame, whose z
      is the vertical used by ``xy_only`` and ``"4dof"``.
    - ``"se3"``: least-squares rigid alignment of the positions (Umeyama, no scale; evo).
    - ``"4dof"``: least-squares yaw about the world z axis and translation (closed form; the
      DoF a gravity-aware odometry cannot observe), after ``"origin"``.
    """
    est = _check_poses(est_poses, "est_poses")
    gt = _check_poses(gt_poses, "gt_poses")
    if est.shape != gt.shape:
        raise GeometryError(f"est_poses {est.shape} and gt_poses {gt.shape} differ in shape")
    if align == "none":
        return est.copy()
    traj_est, traj_gt = _trajectory(est), _trajectory(gt)
    if align == "se3":
        try:
            traj_est.align(traj_gt)
        except GeometryException as exc:
            raise GeometryError(f"se3 alignment impossible: {exc}") from None
        return np.array(traj_est.poses_se3)
    if align not in ("origin", "4dof"):
        raise ValueError(f"unknown alignment {align!r}; expected one of none, origin, se3, 4dof")
    traj_est.align_origin(traj_gt)
    est = np.array(traj_est.poses_se3)
    if align == "4dof":
        est = _yaw_translation_alignment(est[:, :3, 3], gt[:, :3, 3]) @ est
    return est


def ate(
    est_poses: np.ndarray,
    gt_poses: np.ndarray,
    align: Alignment = "origin",
    xy_only: bool = False,
) -> dict[str, float]:
    """Absolute trajectory error of the positions (evo APE, translation part).

    Args:
        est_poses, gt_poses: (E, 4, 4) poses at the same epochs.
        align: how the estimate is put in the ground truth frame (see :func:`aligned`).
        xy_only: compare horizontal positions only (the 5-DoF odometry does not observe z).

    Returns:
        ``rmse``, ``mean``, ``median``, ``max`` of the per-epoch position errors, metres.
    """
    est = aligned(est_poses, gt_poses, align)
    gt = np.array(gt_poses, dtype=np.float64)
    if xy_only:
        est[:, 2, 3] = 0.0
        gt[:, 2, 3] = 0.0
    metric = evo_metrics.APE(evo_metrics.PoseRelation.translation_part)
    metric.process_data((_trajectory(gt), _trajectory(est)))
    return _stats(metric)


def rpe(
    est_poses: np.ndarray,
    gt_poses: np.ndarray,
    delta: int = 1,
    all_pairs: bool = True,
    index: np.ndarray | None = None,
) -> dict[str, dict[str, float]]:
    """Relative pose error over ``delta`` epochs (evo RPE).

    For each pair ``(i, i + delta)`` the error is ``inv(gt_i_j) @ est_i_j``; it needs no
    alignment.

    Args:
        est_poses, gt_poses: (E, 4, 4) poses at the same epochs, E > delta.
        delta: epochs between the two poses of a pair (>= 1).
        all_pairs: a pair starts at every epoch (overlapping windows); with False only at
            epochs 0, delta, 2 delta, ... (evo's default). Same for ``delta = 1``.
        index: (E,) increasing epoch numbers of the poses when some epochs are left out
            (those without a reference pose); a pair is then only two poses ``delta``
            epochs apart within a run of consecutive epochs, never one across a gap. None:
            the poses are consecutive epochs.

    Returns:
        ``{"translation": stats (m), "rotation": stats (deg)}`` with ``rmse``, ``mean``,
        ``median``, ``max``.
    """
    est = _check_poses(est_poses, "est_poses")
    gt = _check_poses(gt_poses, "gt_poses")
    if est.shape != gt.shape:
        raise GeometryError(f"est_poses {est.shape} and gt_poses {gt.shape} differ in shape")
    if not (isinstance(delta, int | np.integer) and 1 <= delta < len(est)):
        raise GeometryError(f"RPE delta must be an integer in [1, {len(est) - 1}], got {delta!r}")
    runs = consecutive_runs(index, len(est))
    if len(runs) > 1:
        return _rpe_over_runs(est, gt, int(delta), all_pairs, runs)
    return {key: _stats(m) for key, m in _evo_rpe(est, gt, int(delta), all_pairs).items()}


def _evo_rpe(
    est: np.ndarray, gt: np.ndarray, delta: int, all_pairs: bool
) -> dict[str, evo_metrics.RPE]:
    """evo's RPE metrics (``translation``, ``rotation``) of consecutive poses, processed."""
    out = {}
    for key, relation in (
        ("translation", evo_metrics.PoseRelation.translation_part),
        ("rotation", evo_metrics.PoseRelation.rotation_angle_deg),
    ):
        metric = evo_metrics.RPE(
            relation, delta=delta, delta_unit=evo_metrics.Unit.frames, all_pairs=all_pairs
        )
        metric.process_data((_trajectory(gt), _trajectory(est)))
        out[key] = metric
    return out


def consecutive_runs(index: np.ndarray | None, n: int) -> list[slice]:
    """The runs of consecutive epoch numbers in ``index`` (n,) (increasing), as slices of
    it; one slice over all n without ``index``."""
    if index is None:
        return [slice(0, n)]
    index = np.asarray(index, dtype=np.int64)
    if len(index) != n or np.any(np.diff(index) <= 0):
        raise GeometryError(f"index: expected {n} increasing epoch numbers, got {index!r}")
    cuts = [0, *(np.flatnonzero(np.diff(index) != 1) + 1).tolist(), n]
    return [slice(a, b) for a, b in zip(cuts[:-1], cuts[1:], strict=True)]


def _rpe_over_runs(
    est: np.ndarray, gt: np.ndarray, delta: int, all_pairs: bool, runs: list[slice]
) -> dict[str, dict[str, float]]:
    """:func:`rpe` over the pairs within each run, pooled (evo's statistics of the errors)."""
    errors: dict[str, list[np.ndarray]] = {"translation": [], "rotation": []}
    for run in runs:
        if run.stop - run.start > delta:
            for key, metric in _evo_rpe(est[run], gt[run], delta, all_pairs).items():
                errors[key].append(np.asarray(metric.error, dtype=np.float64))
    if not errors["translation"]:
        raise GeometryError(f"RPE: no two poses {delta} epoch(s) apart without a gap")
    out = {}
    for key, chunks in errors.items():
        e = np.concatenate(chunks)
        stats = (np.sqrt(np.mean(e**2)), np.mean(e), np.median(e), np.max(e))
        out[key] = {k: float(v) for k, v in zip(STATISTICS, stats, strict=True)}
    return out


def drift(est_poses: np.ndarray, gt_poses: np.ndarray, xy_only: bool = False) -> dict[str, float]:
    """Final position error after origin alignment, and relative to the distance travelled.

    Returns:
        ``final_error`` (m) at the last epoch, ``distance`` (m) the length of the ground
        truth path, ``percent`` = 100 * final_error / distance (NaN for a standing vehicle).
        With ``xy_only`` all three are horizontal.

    Across a gap in the reference (epochs left out, see :func:`summarize`'s ``index``) the
    distance takes the straight line between the poses on either side: the path there is
    unknown and at least that long, so the percent is an upper bound. Leaving the gap out
    instead would be a looser one, as the final error holds the drift over the gap too (an
    estimate at 10 Hz with a 3 s gap of 10 s: 1.30 % with the straight line, 1.92 % without
    the gap, 1.30 % against the whole reference; docs/RESULTS.md).
    """
    est = aligned(est_poses, gt_poses, "origin")
    gt = np.asarray(gt_poses, dtype=np.float64)
    dims = slice(0, 2) if xy_only else slice(0, 3)
    final = float(np.linalg.norm(est[-1, dims, 3] - gt[-1, dims, 3]))
    distance = float(np.linalg.norm(np.diff(gt[:, dims, 3], axis=0), axis=1).sum())
    percent = 100.0 * final / distance if distance > 0 else float("nan")
    return {"final_error": final, "distance": distance, "percent": percent}


def per_epoch_errors(est_rel: np.ndarray, gt_rel: np.ndarray) -> dict[str, np.ndarray]:
    """Signed errors of the estimated per-epoch increments in the 5 observed DoF.

    With ``pose5`` = :func:`planodom.geometry.pose5_from_transform` (roll, pitch, yaw, x, y),
    the error of epoch k is ``pose5(est_rel[k]) - pose5(gt_rel[k])``, the angles wrapped to
    [-pi, pi): the estimated roll / pitch / yaw rate (rad per epoch) and x / y displacement
    (m, in the base frame of epoch k) minus the true ones. This is what the paper's tables
    summarise by mean (bias) and standard deviation per DoF. (The alternative,
    ``pose5(inv(gt_rel) @ est_rel)``, agrees to first order for small increments but
    rotates the translation error by the true increment.)

    Args:
        est_rel, gt_rel: (E-1, 4, 4) increments ``T_k_k+1`` (see :func:`relative_motions`).

    Returns:
        ``{"roll", "pitch", "yaw"}`` (E-1,) rad and ``{"x", "y"}`` (E-1,) m.
    """
    est = np.asarray(est_rel, dtype=np.float64)
    gt = np.asarray(gt_rel, dtype=np.float64)
    if est.shape != gt.shape or est.ndim != 3 or est.shape[1:] != (4, 4):
        raise GeometryError(f"expected two (K, 4, 4) arrays, got {est.shape} and {gt.shape}")
    diff = pose5_from_transform(est) - pose5_from_transform(gt)
    diff[:, :3] = (diff[:, :3] + np.pi) % (2.0 * np.pi) - np.pi
    return {name: diff[:, j] for j, name in enumerate(POSE5_NAMES)}


def summarize(
    est_poses: np.ndarray,
    gt_poses: np.ndarray,
    align: Alignment = "origin",
    delta: int = 1,
    xy_only: bool = False,
    index: np.ndarray | None = None,
) -> dict[str, float]:
    """Every metric in one flat dict for a results table; keys end with their unit.

    Keys: ``epochs``; ``ate_{rmse,mean,median,max}_m``; ``rpe_trans_{...}_m`` and
    ``rpe_rot_{...}_deg``; ``drift_m``, ``drift_percent``, ``distance_m``; and for each of
    roll, pitch, yaw (deg per epoch) and x, y (m per epoch) the mean and std of the
    per-epoch errors, e.g. ``yaw_err_mean_deg``, ``x_err_std_m``. RPE and per-epoch entries
    are NaN for a single epoch. ``index`` (E,): the poses' epoch numbers when some epochs
    are left out; RPE and per-epoch errors then take no pair across a gap (:func:`rpe`);
    the drift's distance takes the straight line across it (:func:`drift`).
    """
    est = _check_poses(est_poses, "est_poses")
    gt = _check_poses(gt_poses, "gt_poses")
    out: dict[str, float] = {"epochs": float(len(est))}
    for key, value in ate(est, gt, align, xy_only).items():
        out[f"ate_{key}_m"] = value
    runs = consecutive_runs(index, len(est))
    enough = any(r.stop - r.start > delta for r in runs)
    rel = rpe(est, gt, delta, index=index) if enough else None
    for part, prefix, unit in (("translation", "trans", "m"), ("rotation", "rot", "deg")):
        for key in STATISTICS:
            out[f"rpe_{prefix}_{key}_{unit}"] = rel[part][key] if rel else float("nan")
    d = drift(est, gt, xy_only)
    out |= {"drift_m": d["final_error"], "drift_percent": d["percent"], "distance_m": d["distance"]}
    step = np.ones(len(est) - 1, dtype=bool) if index is None else np.diff(index) == 1
    errors = per_epoch_errors(relative_motions(est)[step], relative_motions(gt)[step])
    for name in POSE5_NAMES:
        scale, unit = (np.degrees(1.0), "deg") if name in ("roll", "pitch", "yaw") else (1.0, "m")
        e = errors[name] * scale
        out[f"{name}_err_mean_{unit}"] = float(e.mean()) if len(e) else float("nan")
        out[f"{name}_err_std_{unit}"] = float(e.std()) if len(e) else float("nan")
    return out


def pose_nees(
    poses: np.ndarray,
    covariances: np.ndarray,
    gt_poses: np.ndarray,
    dofs: Sequence[int] = range(6),
) -> np.ndarray:
    """Per-epoch NEES (E,) of estimated poses against the truth, over tangent components ``dofs``.

    ``xi = Local(T_est, T_true)`` in gtsam's Pose3 tangent at the estimate
    (rot x, y, z in rad, then x, y, z in m, body frame: the frame of gtsam's marginal
    covariances) and ``NEES = xi_d^T P_dd^-1 xi_d``, ``P_dd`` the sub-block of ``dofs``
    (the other components marginalised); e.g. ``dofs=range(5)`` leaves out body z, which a
    5-DoF odometry does not observe. An honest covariance gives NEES ~ chi2(len(dofs)).

    Args:
        poses: (E, 4, 4) estimates. covariances: (E, 6, 6) their covariances in that
            tangent. gt_poses: (E, 4, 4) the truth, in the same frame as the estimates.

    Returns:
        (E,) float64; NaN where ``P_dd`` is singular.
    """
    return errors_nees(pose_errors(poses, gt_poses), covariances, dofs)


def pose_errors(poses: np.ndarray, gt_poses: np.ndarray) -> np.ndarray:
    """(E, 6) ``Local(T_est, T_true)`` in gtsam's Pose3 tangent at the estimate.

    Rot x, y, z in rad, then x, y, z in m, body frame (the tangent of :func:`pose_nees`).

    Args:
        poses: (E, 4, 4) estimates. gt_poses: (E, 4, 4) the truth, in the same frame.
    """
    return np.array(
        [
            np.asarray(gtsam.Pose3(T).localCoordinates(gtsam.Pose3(G)))
            for T, G in zip(poses, gt_poses, strict=True)
        ]
    ).reshape(len(poses), 6)


def errors_nees(
    errors: np.ndarray, covariances: np.ndarray, dofs: Sequence[int] = range(6)
) -> np.ndarray:
    """(E,) NEES ``xi_d^T P_dd^-1 xi_d`` of tangent errors over the components ``dofs``.

    Args:
        errors: (E, 6) as :func:`pose_errors` gives them. covariances: (E, 6, 6).

    Returns:
        (E,) float64; NaN where ``P_dd`` is singular.
    """
    keep = list(dofs)
    block = np.ix_(keep, keep)
    out = np.full(len(errors), np.nan)
    for k, (xi, P) in enumerate(zip(errors, covariances, strict=True)):
        e = xi[keep]
        try:
            out[k] = e @ np.linalg.solve(P[block], e)
        except np.linalg.LinAlgError:
            continue
    return out


# --------------------------------------------------------------------------- helpers


def _check_poses(poses: np.ndarray, name: str) -> np.ndarray:
    arr = np.asarray(poses, dtype=np.float64)
    if arr.ndim != 3 or arr.shape[1:] != (4, 4) or len(arr) == 0:
        raise GeometryError(f"{name}: expected an (E, 4, 4) array with E >= 1, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise GeometryError(f"{name}: poses are not finite")
    return arr


def _trajectory(poses: np.ndarray) -> PoseTrajectory3D:
    """An evo trajectory on copies of ``poses`` (evo mutates them), stamps 0, 1, ..."""
    return PoseTrajectory3D(
        poses_se3=[p.copy() for p in poses], timestamps=np.arange(len(poses), dtype=float)
    )


def _stats(metric: evo_metrics.PE) -> dict[str, float]:
    stats = metric.get_all_statistics()
    return {key: float(stats[key]) for key in STATISTICS}


def _yaw_translation_alignment(p_est: np.ndarray, p_gt: np.ndarray) -> np.ndarray:
    """(4, 4) ``T = [Rz(theta) | t]`` minimising ``sum |T p_est - p_gt|^2`` (closed form).

    With centred positions ``a = p_est - mean``, ``b = p_gt - mean`` the optimal angle is
    ``atan2(sum(a_x b_y - a_y b_x), sum(a_x b_x + a_y b_y))``, then ``t = mean_gt - R mean_est``.
    """
    a = p_est - p_est.mean(axis=0)
    b = p_gt - p_gt.mean(axis=0)
    theta = np.arctan2(
        np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]), np.sum(a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1])
    )
    c, s = np.cos(theta), np.sin(theta)
    T = np.eye(4)
    T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = p_gt.mean(axis=0) - T[:3, :3] @ p_est.mean(axis=0)
    return T
