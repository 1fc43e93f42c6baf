"""Seeded synthetic smoothing problems: a trajectory among planes, noisy planes and 5-DoF poses.

The noise follows the smoothing graph's models exactly, so estimates can be checked
against their covariances: relative rotations ``R_true Exp(n_rot)``, horizontal
translations ``t_true[:2] + n_xy`` (z reported as 0, unobserved), planes
``OrientedPlane3(true).retract(n_plane)`` with a (4, 4) fit covariance whose projection on
the measured plane's tangent basis is the sampling covariance (isotropic in the normal,
with a random normal-offset correlation). The truth's height is a random walk with the sigma of the
graph's vertical factor.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import gtsam
import numpy as np

from planodom.geometry import Plane, invert_transform, make_transform, transform_from_rpy_xyz
from planodom.odometry.relative import RelativePose


@dataclass(frozen=True, eq=False)
class SyntheticSequence:
    """A synthetic smoothing problem.

    Attributes:
        poses: (E, 4, 4) true ``T_world_base``, the first one the identity.
        planes: per epoch, the measured planes (base frame, normals towards the sensor,
            ``truth_id`` the wall index).
        relatives: the measured relative poses for delta = 1..D.
        walls: (N, 4) true world planes ``(n, d)``.
        centres: (N, 3) centres of the walls' visible patches, metres.
    """

    poses: np.ndarray
    planes: list[list[Plane]]
    relatives: list[RelativePose]
    walls: np.ndarray
    centres: np.ndarray


def _trajectory(rng: np.random.Generator, n: int, step: float, vertical_sigma: float) -> np.ndarray:
    """(n, 4, 4) a smooth wandering path with small roll and pitch, first pose identity."""
    yaw_rate = np.convolve(rng.normal(0.0, 0.08, n + 20), np.ones(10) / 10, "same")[10 : n + 10]
    yaw = np.concatenate([[0.0], np.cumsum(yaw_rate[1:])])
    xy = np.zeros((n, 2))
    xy[1:] = np.cumsum(step * np.column_stack([np.cos(yaw[:-1]), np.sin(yaw[:-1])]), axis=0)
    z = np.concatenate([[0.0], np.cumsum(rng.normal(0.0, vertical_sigma, n - 1))])
    roll = 0.01 * np.sin(np.arange(n) * 0.3) * (np.arange(n) > 0)
    pitch = 0.015 * np.sin(np.arange(n) * 0.2 + 1.0) - 0.015 * np.sin(1.0)
    return np.stack(
        [
            transform_from_rpy_xyz(roll[k], pitch[k], yaw[k], xy[k][0], xy[k][1], z[k])
            for k in range(n)
        ]
    )


def _walls(
    rng: np.random.Generator, poses: np.ndarray, per_epoch: float, ground: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Vertical walls near the path (random orientation) plus optionally a ground plane."""
    count = max(4, int(per_epoch * len(poses)))
    anchors = poses[rng.integers(0, len(poses), count), :3, 3]
    centres = anchors + np.column_stack([rng.uniform(-15, 15, (count, 2)), np.zeros(count)])
    heading = rng.uniform(0, 2 * np.pi, count)
    normals = np.column_stack([np.cos(heading), np.sin(heading), np.zeros(count)])
    if ground:
        normals = np.vstack([normals, [0.0, 0.0, 1.0]])
        centres = np.vstack([centres, [0.0, 0.0, -1.5]])
    offsets = -np.einsum("ij,ij->i", normals, centres)
    # Face the wall towards the pose it was placed near (it is seen from that side only).
    side = np.sign(np.einsum("ij,ij->i", normals[:count], anchors) + offsets[:count])
    normals[:count] *= np.where(side == 0, 1.0, side)[:, None]
    offsets[:count] *= np.where(side == 0, 1.0, side)
    return np.column_stack([normals, offsets]), centres


def _measure_plane(
    rng: np.random.Generator,
    wall: np.ndarray,
    T_world_base: np.ndarray,
    sigma_normal: float,
    sigma_offset: float,
    truth_id: int,
) -> Plane:
    """A noisy plane in the base frame, normal towards the sensor, with its covariance."""
    true_body = gtsam.OrientedPlane3(wall).transform(gtsam.Pose3(T_world_base))
    c = np.asarray(true_body.planeCoefficients())
    if c[3] < 0:  # orient towards the sensor (origin on the positive side)
        true_body = gtsam.OrientedPlane3(-c)
    # Tangent covariance: isotropic normal, one normal axis correlated with the offset (as
    # for a fit whose centroid is off the sensor).
    rho = rng.uniform(-0.8, 0.8)
    tangent = np.diag([sigma_normal**2, sigma_normal**2, sigma_offset**2])
    tangent[0, 2] = tangent[2, 0] = rho * sigma_normal * sigma_offset
    xi = rng.multivariate_normal(np.zeros(3), tangent) if sigma_normal > 0 else np.zeros(3)
    measured = np.asarray(true_body.retract(xi).planeCoefficients())
    B = np.asarray(gtsam.Unit3(measured[:3]).basis())
    P = np.zeros((4, 3))
    P[:3, :2] = B
    P[3, 2] = 1.0
    cov = P @ tangent @ P.T
    return Plane(measured[:3], measured[3], covariance=cov, truth_id=truth_id)


def make_sequence(
    n_epochs: int = 40,
    seed: int = 0,
    *,
    delta_max: int = 3,
    step_m: float = 1.0,
    walls_per_epoch: float = 0.6,
    visible_range_m: float = 25.0,
    ground: bool = True,
    sigma_rotation: float = 0.0,
    sigma_translation: float = 0.0,
    sigma_normal: float = 0.0,
    sigma_offset: float = 0.0,
    vertical_sigma: float = 0.05,
    origin: np.ndarray | None = None,
) -> SyntheticSequence:
    """A seeded synthetic sequence (all sigmas 0: noiseless, exact measurements).

    Args:
        n_epochs: E.
        seed: random seed (trajectory, walls and noise).
        delta_max: relative poses for delta = 1..D.
        step_m: distance travelled per epoch, metres.
        walls_per_epoch: number of walls per epoch of trajectory.
        visible_range_m: a wall is seen when its patch centre is this close, metres.
        ground: add a horizontal ground plane 1.5 m below the start (it observes z).
        sigma_rotation, sigma_translation: relative pose noise per axis, rad and m; also
            the reported sigmas (floored at 1e-6 for noiseless data).
        sigma_normal, sigma_offset: plane noise (tangent, rad; offset, m); also the
            reported covariance.
        vertical_sigma: sigma of the truth's height random walk per epoch, metres.
        origin: (3,) translation of the whole scene and trajectory (far-from-origin tests).
    """
    rng = np.random.default_rng(seed)
    poses = _trajectory(rng, n_epochs, step_m, vertical_sigma)
    walls, centres = _walls(rng, poses, walls_per_epoch, ground)
    if origin is not None:
        shift = make_transform(np.eye(3), origin)
        poses = shift @ poses
        centres = centres + origin
        walls = np.column_stack([walls[:, :3], walls[:, 3] - walls[:, :3] @ origin])
    near = np.linalg.norm(poses[:, None, :2, 3] - centres[None, :, :2], axis=2) < visible_range_m
    in_front = poses[:, :3, 3] @ walls[:, :3].T + walls[:, 3] > 0.5
    visible = near & in_front
    if ground:
        visible[:, -1] = True
    planes: list[list[Plane]] = []
    ids: list[np.ndarray] = []
    for k in range(n_epochs):
        seen = np.flatnonzero(visible[k])
        planes.append(
            [
                _measure_plane(rng, walls[w], poses[k], sigma_normal, sigma_offset, int(w))
                for w in seen
            ]
        )
        ids.append(seen)
    sigmas = np.maximum([sigma_rotation] * 3 + [sigma_translation] * 2, 1e-6)
    relatives = []
    for k in range(1, n_epochs):
        for delta in range(1, min(delta_max, k) + 1):
            prev = k - delta
            T_true = invert_transform(poses[prev]) @ poses[k]
            R = T_true[:3, :3] @ gtsam.Rot3.Expmap(rng.normal(0.0, sigma_rotation, 3)).matrix()
            t = np.append(T_true[:2, 3] + rng.normal(0.0, sigma_translation, 2), 0.0)
            common, i_prev, i_curr = np.intersect1d(ids[prev], ids[k], return_indices=True)
            relatives.append(
                RelativePose(
                    make_transform(R, t),
                    np.diag(sigmas**2),
                    associations=np.column_stack([i_prev, i_curr]),
                    prev=prev,
                    curr=k,
                )
            )
    return SyntheticSequence(poses, planes, relatives, walls, centres)


def with_deskew_jacobians(
    seq: SyntheticSequence, *, jacobians: bool = True, spread: bool = True, seed: int = 5
) -> tuple[list[list[Plane]], list[RelativePose]]:
    """``seq``'s planes and relative poses as the sandwich covariances see them: each plane
    with a random (4, 6) deskewing Jacobian (N(0, 0.2²) entries, seeded) or none, and the
    relative poses of scans spread in time (``time_spread``) or taken at one instant."""
    rng = np.random.default_rng(seed)
    planes = [
        [replace(p, deskew_jacobian=rng.normal(scale=0.2, size=(4, 6)) if jacobians else None)
         for p in ps]
        for ps in seq.planes
    ]  # fmt: skip
    return planes, [replace(r, time_spread=spread) for r in seq.relatives]
