"""Seeded synthetic plane sets for the association, consensus and odometry tests."""

from __future__ import annotations

import numpy as np

from planodom.geometry import (
    Plane,
    PlaneSupport,
    invert_transform,
    transform_from_rpy_xyz,
)


def square_polygon(centroid: np.ndarray, normal: np.ndarray, half: float) -> np.ndarray:
    """(4, 3) square of half-size ``half`` (m) around ``centroid`` in the plane of ``normal``."""
    a = np.cross(normal, [0.0, 0.0, 1.0] if abs(normal[2]) < 0.9 else [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    return centroid + half * np.array([a + b, -a + b, -a - b, a - b])


def world_planes(rng: np.random.Generator, n_walls: int = 6, ground: bool = True) -> list[Plane]:
    """Random vertical-ish walls around the origin (3..20 m away) and optionally a ground.

    Normals point towards the origin; walls are tilted up to 10 deg from vertical and
    have random confidences and square supports facing the origin.
    """
    planes = []
    for k in range(n_walls):
        az = rng.uniform(-np.pi, np.pi)
        tilt = rng.uniform(-0.17, 0.17)
        n = -np.array([np.cos(az) * np.cos(tilt), np.sin(az) * np.cos(tilt), np.sin(tilt)])
        dist = rng.uniform(3.0, 20.0)
        c = -dist * n + rng.uniform(-2, 2) * np.array([-n[1], n[0], 0.0])
        c[2] = rng.uniform(0.0, 2.0)
        support = PlaneSupport(c, square_polygon(c, n, rng.uniform(1.0, 4.0)), 100)
        planes.append(Plane(n, float(-n @ c), confidence=rng.uniform(0.3, 1.0),
                            support=support, truth_id=k))  # fmt: skip
    if ground:
        c = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), -1.5])
        n = np.array([0.0, 0.0, 1.0])
        support = PlaneSupport(c, square_polygon(c, n, 6.0), 500)
        planes.append(Plane(n, 1.5, confidence=rng.uniform(0.3, 1.0), support=support,
                            truth_id=n_walls))  # fmt: skip
    return planes


def observe(planes_world: list[Plane], T_world_base: np.ndarray) -> list[Plane]:
    """The planes as seen from ``T_world_base``: in the base frame, normals towards it."""
    T_base_world = invert_transform(T_world_base)
    return [p.transformed(T_base_world).oriented_towards(np.zeros(3)) for p in planes_world]


def random_motion(
    rng: np.random.Generator, max_angle_deg: float = 5.0, max_xy: float = 0.5, tz: float = 0.0
) -> np.ndarray:
    """A random relative transform with small roll/pitch/yaw and horizontal translation."""
    r = np.radians(rng.uniform(-max_angle_deg, max_angle_deg, 3)) * [0.3, 0.3, 1.0]
    x, y = rng.uniform(-max_xy, max_xy, 2)
    return transform_from_rpy_xyz(r[0], r[1], r[2], x, y, tz)


def noisy(planes: list[Plane], rng: np.random.Generator, angle_sigma: float, d_sigma: float):
    """Perturb normals (rad) and offsets (m) with Gaussian noise."""
    out = []
    for p in planes:
        n = p.normal + rng.normal(0, angle_sigma, 3)
        out.append(Plane(n, p.offset + rng.normal(0, d_sigma), confidence=p.confidence,
                         support=p.support, truth_id=p.truth_id))  # fmt: skip
    return out


def with_covariances(planes, rng: np.random.Generator):
    """``planes`` (a PlaneSet) with random (n, d) covariances (positive definite)."""
    from dataclasses import replace

    A = rng.normal(0.0, 1e-3, (len(planes), 4, 4))
    return replace(planes, covariances=A @ A.transpose(0, 2, 1) + 1e-8 * np.eye(4))


def observed_pair(world: list[Plane], T: np.ndarray, rng: np.random.Generator, covariances=False):
    """(prev, curr) PlaneSets: ``world`` observed from the identity and from ``T`` (4, 4),
    each noisy (0.004 rad, 0.01 m: :func:`noisy`), then, with ``covariances``, each given
    random covariances (:func:`with_covariances`), drawing from ``rng`` in that order."""
    from planodom.planes import PlaneSet

    prev = PlaneSet.from_planes(noisy(observe(world, np.eye(4)), rng, 0.004, 0.01))
    curr = PlaneSet.from_planes(noisy(observe(world, T), rng, 0.004, 0.01))
    if covariances:
        prev, curr = with_covariances(prev, rng), with_covariances(curr, rng)
    return prev, curr
