"""Plane landmark factors between a ``Pose3`` and an ``OrientedPlane3`` landmark.

Two forms of the same measurement (the plane ``n . p + d = 0`` seen in the base frame of
the observing pose, normal towards the sensor):

- **global**: the landmark lives in the world frame, ``gtsam.OrientedPlane3Factor``. Its
  Jacobians w.r.t. the landmark's normal grow with the distance of the observing pose from
  the world origin (rotating a world plane about the point closest to the origin moves
  it by that lever arm at the sensor), so far from the origin the landmark's information
  matrix is badly conditioned: borglab/gtsam#561 and the tests of PR #564 / #680
  (a pose about 100 m out, plane Hessian with condition number ~5e7) end in
  ``IndeterminantLinearSystemException``. Robust noise models cannot be attached (the
  Python constructor takes only a Gaussian model).
- **anchored**: the landmark lives in an anchor frame ``A`` near its observations,
  ``gtsam_unstable.LocalOrientedPlane3Factor(pose, anchor, plane)``; the lever arms are
  then bounded by the sensor range. The anchor is its own ``Pose3`` variable with a unit
  prior at a fixed point (identity rotation, the first observing position): it is pure
  gauge, since only ``anchor * plane`` is observed, so the prior fixes it without
  affecting any pose estimate, and it is not tied to a pose key that a fixed-lag smoother
  may marginalise while the landmark is still seen.

Measured normals keep one orientation. ``OrientedPlane3``'s error of a flipped measurement
``(-n, -d)`` has a zero normal part (``Unit3::errorVector`` projects ``-n`` on the tangent
basis of ``n``) and an offset part ``2 d``, near zero for planes through the sensor:
:func:`orient_measurement` detects the flip against the predicted plane before a factor is
built.
"""

from __future__ import annotations

import gtsam
import gtsam_unstable
import numpy as np

from planodom.geometry import make_transform

GaussianNoise = gtsam.noiseModel.Gaussian
Noise = gtsam.noiseModel.Base

#: Default plane measurement noise: Unit3 tangent (2) rad, offset (1) m.
PLANE_NOISE = gtsam.noiseModel.Diagonal.Sigmas(np.array([1e-2, 1e-2, 2e-2]))

#: Prior on an anchor frame: only fixes the gauge, so any well-scaled sigma will do.
ANCHOR_NOISE = gtsam.noiseModel.Isotropic.Sigma(6, 1.0)


def plane_factor(
    pose_key: int, landmark_key: int, measured: np.ndarray, noise: GaussianNoise = PLANE_NOISE
) -> gtsam.OrientedPlane3Factor:
    """Global plane factor between ``T_world_base`` (Pose3 ``pose_key``) and the world
    plane (OrientedPlane3 ``landmark_key``): ``measured`` (4,) ``(n, d)`` in the base frame,
    normal towards the sensor; ``noise`` 3-dim Gaussian in OrientedPlane3 tangent
    coordinates (the Python constructor takes no robust model)."""
    return gtsam.OrientedPlane3Factor(np.asarray(measured, float), noise, pose_key, landmark_key)


def anchored_plane_factor(
    pose_key: int,
    anchor_key: int,
    landmark_key: int,
    measured: np.ndarray,
    noise: Noise = PLANE_NOISE,
) -> gtsam_unstable.LocalOrientedPlane3Factor:
    """Anchored plane factor: the landmark (OrientedPlane3 ``landmark_key``) is expressed in
    the anchor frame ``T_world_anchor`` (Pose3 ``anchor_key``, see :func:`anchor_prior`)
    and observed from ``T_world_base`` (Pose3 ``pose_key``) as ``measured`` (4,) ``(n, d)``
    in the base frame, normal towards the sensor; ``noise`` 3-dim in the measured plane's
    tangent coordinates, may be robust."""
    return gtsam_unstable.LocalOrientedPlane3Factor(
        np.asarray(measured, float), noise, pose_key, anchor_key, landmark_key
    )


def anchor_pose(origin: np.ndarray) -> np.ndarray:
    """``T_world_anchor`` (4, 4): identity rotation at ``origin`` (3,), metres."""
    return make_transform(np.eye(3), origin)


def anchor_prior(
    anchor_key: int,
    T_world_anchor: np.ndarray,
    noise: Noise = ANCHOR_NOISE,
) -> gtsam.PriorFactorPose3:
    """The gauge-fixing prior of an anchor frame (see the module docstring).

    Its sigma does not change any estimate, only the conditioning: scale it like the
    landmark's own measurements (rad and m) so that the gauge directions are neither much
    stiffer nor much softer than the observed ones.
    """
    return gtsam.PriorFactorPose3(anchor_key, gtsam.Pose3(T_world_anchor), noise)


def predict_plane(T_world_base: np.ndarray, plane_world: np.ndarray) -> np.ndarray:
    """(4,) ``(n, d)`` of a world plane (4,) seen from ``T_world_base`` (4, 4)."""
    n_world = plane_world[:3]
    return np.append(
        T_world_base[:3, :3].T @ n_world, plane_world[3] + n_world @ T_world_base[:3, 3]
    )


def orient_measurement(
    measured: np.ndarray, predicted: np.ndarray, max_angle: float = np.pi / 2
) -> tuple[np.ndarray, bool]:
    """Orient a measured plane (4,) like the predicted one (4,) (both in one frame).

    Returns the measurement, negated when its normal is more than ``max_angle`` rad from the
    predicted normal, and whether it was flipped.
    """
    flipped = bool(measured[:3] @ predicted[:3] < np.cos(max_angle))
    return (-measured if flipped else measured), flipped


def plane_noise(
    tangent_covariance: np.ndarray, isotropic_normal: bool = False
) -> gtsam.noiseModel.Gaussian:
    """Gaussian noise model of a plane factor from the measured plane's covariance.

    Args:
        tangent_covariance: (3, 3) covariance of the measured plane in OrientedPlane3
            tangent coordinates (``retract`` / ``localCoordinates``: Unit3 basis (2), d).
        isotropic_normal: replace the (2, 2) normal block by its largest eigenvalue times
            the identity and drop the normal-offset correlation: the global factor
            expresses its error in the tangent basis of the *predicted* normal, which may
            be rotated in the tangent plane with respect to the measured one's.

    ``OrientedPlane3::errorVector`` (used by both factors) does not return tangent
    coordinates: its normal part has the sign of ``localCoordinates`` but its offset part
    the opposite one (``d_this - d_other``; checked in tests/test_factors.py). The error's
    covariance is therefore ``S C S`` with ``S = diag(1, 1, -1)``: the normal-offset
    correlations change sign. Without this, plane fits (whose normal and offset errors are
    strongly correlated when the centroid is far from the sensor) are whitened wrongly.
    """
    cov = np.array(tangent_covariance, dtype=float)
    if isotropic_normal:
        lam = float(np.linalg.eigvalsh(cov[:2, :2])[-1])
        cov = np.diag([lam, lam, cov[2, 2]])
    cov[:2, 2] *= -1.0
    cov[2, :2] *= -1.0
    return gtsam.noiseModel.Gaussian.Covariance(cov)
