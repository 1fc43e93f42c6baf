"""Noise models of the factor graph: between-factor and plane covariances, robust kernels.

Noise comes from the data (the odometry's 5-DoF covariances, the planes' fit
covariances), plus floors in quadrature (noiseless simulations report zero covariances);
the ``default_*`` sigmas of :class:`planodom.config.SmoothingConfig` stand in when an
input carries no uncertainty at all.
"""

from __future__ import annotations

from collections.abc import Sequence

import gtsam
import numpy as np

from planodom.config import SmoothingConfig
from planodom.geometry import Plane, plane_tangent_covariance, rpy_from_rotation
from planodom.odometry.relative import RelativePose
from planodom.smoothing.deskew_noise import TIME_SPREAD, DeskewNoise, plane_deskew_covariance
from planodom.smoothing.plane_share import own_share

#: Default robust kernel parameters (95 % efficiency on Gaussian noise), in sigmas.
ROBUST_DEFAULTS = {"huber": 1.345, "cauchy": 2.3849}


def with_robust_kernel(
    base: gtsam.noiseModel.Base, config: SmoothingConfig
) -> gtsam.noiseModel.Base:
    """``base`` wrapped in the configured robust kernel (``robust_kernel`` not "none")."""
    kernel = config.robust_kernel
    k = config.robust_threshold or ROBUST_DEFAULTS[kernel]
    if kernel == "huber":
        return gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Huber.Create(k), base)
    return gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Cauchy.Create(k), base)


def rpy_to_rotation_vector(rpy: np.ndarray) -> np.ndarray:
    """(3, 3) Jacobian of the body-frame rotation error w.r.t. (roll, pitch, yaw) at ``rpy``.

    For ``R = Rz(yaw) Ry(pitch) Rx(roll)``, ``R(rpy + d) = R Exp(J d)`` to first order; it
    maps a covariance of rpy increments to the tangent of :func:`factors.pose5.pose5_factor`.
    Only roll and pitch matter.
    """
    roll, pitch = rpy[0], rpy[1]
    sr, cr, sp, cp = np.sin(roll), np.cos(roll), np.sin(pitch), np.cos(pitch)
    return np.array([[1.0, 0.0, -sp], [0.0, cr, sr * cp], [0.0, -sr, cr * cp]])


def between_covariance(
    rel: RelativePose, config: SmoothingConfig, deskew: np.ndarray | None = None
) -> np.ndarray:
    """(5, 5) covariance of a relative pose's factor error, or (3, 3) rotation-only.

    The covariance of (roll, pitch, yaw, x, y) (``default_*`` sigmas when unknown) is
    mapped to the factor's rotation-vector tangent (:func:`rpy_to_rotation_vector`) and
    floored in quadrature (``min_*_sigma_*``); plus ``deskew`` (5, 5), the deskewing error
    of its two epochs (:meth:`.deskew_noise.DeskewNoise.relative_covariance`).
    """
    c = config
    if rel.covariance is not None and np.all(np.isfinite(rel.covariance)):
        cov = np.asarray(rel.covariance, dtype=float).reshape(5, 5)
    else:
        cov = np.diag(
            [c.default_rotation_sigma_rad**2] * 3 + [c.default_translation_sigma_m**2] * 2
        )
    J = np.eye(5)
    J[:3, :3] = rpy_to_rotation_vector(rpy_from_rotation(rel.T_prev_curr[:3, :3]))
    floor = [c.min_rotation_sigma_rad**2] * 3 + [c.min_translation_sigma_m**2] * 2
    cov = J @ (0.5 * (cov + cov.T)) @ J.T + np.diag(floor)
    if deskew is not None:
        cov = cov + deskew
    return cov if rel.translation_observed else cov[:3, :3]


def plane_factor_covariance(
    plane: Plane,
    config: SmoothingConfig,
    model: DeskewNoise | None,
    epoch: int,
    jacobian: bool = True,
    share: np.ndarray | None = None,
) -> np.ndarray:
    """(3, 3) :func:`plane_covariance` of ``plane`` seen at epoch ``epoch`` with the
    deskewing error that ``model`` (None: none) gives its plane factors; without
    ``jacobian`` not the change of motion through the plane's own Jacobian (the scale of
    an anchor's prior, pure gauge: a plane whose deskewing leaves it barely known made
    its anchor's marginal indeterminate, world 2). ``share``: (E, 6, 6) the sandwich's
    epochs' deskewing errors, of which the plane's own share is added
    (``smoothing.sandwich_plane_share`` "own", :func:`.plane_share.own_share`)."""
    if model is None:
        cov = plane_covariance(plane, config)
    else:
        change = model.plane_motion_change(epoch) if jacobian else None
        cov = plane_covariance(plane, config, model.plane_pose_covariance(epoch), change)
    if share is not None and jacobian and epoch < len(share):
        cov = cov + own_share(plane, share[epoch])
    return cov


def plane_covariance(
    plane: Plane,
    config: SmoothingConfig,
    deskew: np.ndarray | None = None,
    motion_change: np.ndarray | None = None,
) -> np.ndarray:
    """(3, 3) covariance of a measured plane in OrientedPlane3 tangent coordinates: its fit
    covariance (``default_plane_*`` sigmas when unknown; divided by its confidence with
    ``plane_confidence_scaling``), floored in quadrature, plus the share of ``deskew``
    (6, 6), its epoch's deskewing perturbation (:func:`.deskew_noise.plane_deskew_covariance`),
    plus ``motion_change`` (6, 6), the covariance of the change of motion over the epoch
    its points were deskewed without, through the plane's own ``deskew_jacobian`` (a plane
    without one: as a rigid perturbation of a third of it, ``deskew``'s model)."""
    c = config
    if plane.covariance is not None and np.all(np.isfinite(plane.covariance)):
        cov = plane_tangent_covariance(plane)
        cov = 0.5 * (cov + cov.T)
    else:
        n2, d2 = c.default_plane_normal_sigma_rad**2, c.default_plane_offset_sigma_m**2
        cov = np.diag([n2, n2, d2])
    floor = np.diag([c.min_plane_normal_sigma_rad**2] * 2 + [c.min_plane_offset_sigma_m**2])
    if c.plane_confidence_scaling:
        cov = cov * (1.0 / plane.confidence)
    if deskew is not None:
        cov = cov + plane_deskew_covariance(plane.normal, deskew)
    if motion_change is not None and plane.deskew_jacobian is not None:
        P = np.zeros((4, 3))  # (n, d) -> tangent, as plane_tangent_covariance
        P[:3, :2] = np.asarray(gtsam.Unit3(plane.normal).basis())
        P[3, 2] = 1.0
        J = P.T @ plane.deskew_jacobian
        cov = cov + J @ motion_change @ J.T
    elif motion_change is not None:
        cov = cov + plane_deskew_covariance(plane.normal, TIME_SPREAD * motion_change)
    return cov + floor


def loop_deskew_model(
    config: SmoothingConfig, relatives: Sequence[RelativePose]
) -> DeskewNoise | None:
    """``smoothing.loop_factor_deskew`` "both_epochs" with ``deskew_noise`` "none": the
    "twist_change" model of the deskewing error (:class:`.DeskewNoise`) fed the whole run's
    ``relatives``, for the loop-candidate factors alone; None otherwise (with a
    ``deskew_noise`` model the loop factors take that one's)."""
    if config.loop_factor_deskew == "off" or config.deskew_noise != "none":
        return None
    model = DeskewNoise()
    for rel in relatives:
        model.add(rel)
    return model
