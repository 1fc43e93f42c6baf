"""The plane-map registration as a :class:`RelativePose`: 5x5 covariance and status.

The registration's information ``H`` (6, 6) is of the world-frame perturbation ``R <-
exp(w) R, t <- t + dt`` of the scan's pose, the previous pose held fixed. For ``T_rel =
inv(P) T`` that is ``w_rel = R_P^T w``, ``dt_rel = R_P^T dt``. The covariance is ``(H +
H_0)^-1`` with the weak prior ``H_0 = diag(1 / bound^2)`` of the association's motion bounds
(so a direction nothing observes gets the squared bound, as the paper's solver reports
unmeasured DoF), mapped to (roll, pitch, yaw, x, y) through the Jacobian of the Euler
angles (central differences) and floored by ``odometry.min_sigma_*``.

Status: rotation directions with a 1-sigma above ``unobserved_rotation_deg`` -> UNRESOLVED
(all of them, or some with ``planemap.partial_rotation: unresolved``; with ``prediction``
the rotation about those axes is the constant-velocity prediction's, with its uncertainty,
and the pose is ``rotation_partly_observed``, :func:`predicted_about_unobserved`);
a horizontal translation direction above ``unobserved_translation_m`` -> DEGENERATE
(rotation only; with ``planemap.degenerate_translation: prediction`` the translation along
the directions above that limit is the constant-velocity prediction's, with its
uncertainty, :func:`predicted_along_unobserved`); the vertical is ``z_observed`` when
its sigma is within that limit, and when not, with ``planemap.reference_time: middle``,
the prediction's too (with ``prediction``), the status unchanged: issue 11's lidar
world 19 (an indoor corridor, a 16-beam lidar that sees neither floor nor a ceiling
patch twice in its first scans) drifted 1.27 m vertically in its second scan, and the
25 m/s vertical twist that step gave deskewed the next ones (ATE 41 -> 3.9 mm at 6 mm,
sweeps registered at their middle); with ``epoch``, whose averaged own twist damps it,
world 3 at 2 cm went 4.5 -> 63 mm with it, so there the vertical stays as registered.
The pose the odometry keeps (its map update and next prediction) is the one reported,
whatever of it came from the prediction (``planemap.kept_pose: reported``, the default;
figures there); with ``registration`` it is where Gauss-Newton ended but for a
degenerate epoch's unobserved translation (generalisation world 75 at 6 mm: the vertical
predicted here, the pose kept 0.36 m off along it, the next epochs 10 m off vertically).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planodom.geometry import rpy_from_rotation
from planodom.odometry.relative import RelativePose, Status
from planodom.rotvec import rotation_matrices, rotation_vectors

if TYPE_CHECKING:
    from planodom.config import PlanemapConfig
    from planodom.odometry.planemap.odometry import PlaneMapOdometry


def rpy_jacobian(R: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """(3, 3) d(roll, pitch, yaw) / dw of ``exp(w) R`` at w = 0 (central differences);
    the six rotations go through scipy in one call each way (per rotation the same
    values as one call each)."""
    w = np.concatenate([np.eye(3) * h, -np.eye(3) * h])  # +h e_k, then -h e_k
    moved = rotation_matrices(w) @ R  # one 3 x 3 product each (as one at a time)
    rpy = rpy_from_rotation(moved)
    return np.angle(np.exp(1j * (rpy[:3] - rpy[3:]))).T / (2 * h)


def relative_pose(
    odo: PlaneMapOdometry, T_rel: np.ndarray, H: np.ndarray | None, status: Status
) -> RelativePose:
    """The :class:`RelativePose` of ``T_rel`` with information ``H`` (module docstring)."""
    cfg = odo.config
    rot_b = np.radians(cfg.association.max_rotation_deg)
    tr_b = cfg.association.max_translation_m
    if H is None or status is Status.UNRESOLVED:
        cov5 = np.diag([rot_b**2] * 3 + [tr_b**2] * 2)
        return RelativePose(T_rel.copy(), cov5, Status.UNRESOLVED)
    cov6 = np.linalg.inv(H + np.diag([rot_b**-2] * 3 + [tr_b**-2] * 3))
    Rp = odo.pose[:3, :3]
    B = np.zeros((6, 6))
    B[:3, :3] = B[3:, 3:] = Rp.T
    cov = B @ cov6 @ B.T
    pm = cfg.planemap
    unobserved = np.linalg.eigvalsh(cov[:3, :3]) > np.radians(pm.unobserved_rotation_deg) ** 2
    partial = bool(unobserved.any()) and pm.partial_rotation == "prediction"
    if unobserved.all() or (unobserved.any() and not partial):
        return relative_pose(odo, T_rel, None, Status.UNRESOLVED)
    if partial:
        T_rel, cov = predicted_about_unobserved(T_rel, cov, odo.velocity, odo.sigmas()[0], pm)
    horizontal = np.sqrt(np.linalg.eigvalsh(cov[3:5, 3:5]).max())
    status = Status.DEGENERATE if horizontal > pm.unobserved_translation_m else Status.OK
    sigma_z = float(np.sqrt(cov[5, 5]))
    z_observed = sigma_z <= pm.unobserved_translation_m
    # with sweeps registered at their middle, the vertical too when unobserved (an OK
    # epoch): Gauss-Newton drifts along it on next to nothing, and the step's own twist,
    # used as it is there (not averaged), deskews the next epochs with that drift
    vertical = not z_observed and pm.reference_time == "middle"
    unobserved_translation = status is Status.DEGENERATE or vertical
    if unobserved_translation and pm.degenerate_translation == "prediction":
        T_rel, cov = predicted_along_unobserved(T_rel, cov, odo.velocity, odo.sigmas()[1], pm)
    J = np.zeros((5, 6))
    J[:3, :3] = rpy_jacobian(T_rel[:3, :3])
    J[3, 3] = J[4, 4] = 1.0
    cov5 = J @ cov @ J.T
    floors = np.r_[
        [np.radians(cfg.odometry.min_sigma_rotation_deg) ** 2] * 3,
        [cfg.odometry.min_sigma_translation_m**2] * 2,
    ]
    cov5 = cov5 + np.diag(floors)
    return RelativePose(
        T_rel.copy(), cov5, status, z_observed=z_observed,
        sigma_z=sigma_z if z_observed else np.inf, rotation_partly_observed=partial,
    )  # fmt: skip


def predicted_about_unobserved(
    T_rel: np.ndarray,
    cov: np.ndarray,
    T_pred_rel: np.ndarray,
    sigma_pred_rad: float,
    config: PlanemapConfig,
) -> tuple[np.ndarray, np.ndarray]:
    """``T_rel`` (4, 4) with its rotation about the unobserved axes (eigenvectors of the
    rotation block of ``cov`` with a 1-sigma above ``config.unobserved_rotation_deg``) taken
    from the prediction ``T_pred_rel`` (4, 4), and ``cov`` (6, 6, rotation then translation,
    previous frame, left perturbation ``R <- exp(w) R``) with those axes' variance the
    prediction's, ``sigma_pred_rad`` squared (cross terms along them dropped with the
    value). The rotation counterpart of :func:`predicted_along_unobserved`: e.g. the ground
    alone fixes roll and pitch; the yaw it leaves free is the prediction's, not wherever
    Gauss-Newton stopped on the weak prior."""
    lam, V = np.linalg.eigh(cov[:3, :3])
    U = V[:, lam > np.radians(config.unobserved_rotation_deg) ** 2]
    P = U @ U.T
    w = rotation_vectors((T_pred_rel[:3, :3] @ T_rel[:3, :3].T)[None])[0]
    out = T_rel.copy()
    out[:3, :3] = rotation_matrices(P @ w) @ T_rel[:3, :3]
    A = np.eye(6)
    A[:3, :3] -= P
    cov = A @ cov @ A.T
    cov[:3, :3] += sigma_pred_rad**2 * P
    return out, cov


def predicted_along_unobserved(
    T_rel: np.ndarray,
    cov: np.ndarray,
    T_pred_rel: np.ndarray,
    sigma_pred_m: float,
    config: PlanemapConfig,
) -> tuple[np.ndarray, np.ndarray]:
    """``T_rel`` (4, 4) with its translation along the unobserved directions (eigenvectors
    of the translation block of ``cov`` with a 1-sigma above
    ``config.unobserved_translation_m``) taken from the prediction ``T_pred_rel`` (4, 4),
    and ``cov`` (6, 6, rotation then translation, previous frame) with those directions'
    variance the prediction's, ``sigma_pred_m`` squared (the RMS deviation of the
    constant-velocity model; rotation cross terms along them dropped with the value)."""
    lam, V = np.linalg.eigh(cov[3:, 3:])
    U = V[:, lam > config.unobserved_translation_m**2]  # (3, u)
    P = U @ U.T  # projector on the unobserved directions
    out = T_rel.copy()
    out[:3, 3] = T_rel[:3, 3] + P @ (T_pred_rel[:3, 3] - T_rel[:3, 3])
    A = np.eye(6)
    A[3:, 3:] -= P
    cov = A @ cov @ A.T
    cov[3:, 3:] += sigma_pred_m**2 * P
    return out, cov
