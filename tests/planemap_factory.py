"""Shared factories of the plane-map odometry tests: planes of point sets with moments."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from planodom.geometry import Plane, PlaneSupport


def plane_points(rng, n, d, centre, size, count, noise=0.0):
    """``count`` points on the plane (n, d) around the foot of ``centre``, square ``size``."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    a = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    c0 = np.asarray(centre, float) - (n @ centre + d) * n
    uv = rng.uniform(-size / 2, size / 2, (count, 2))
    return c0 + uv[:, :1] * a + uv[:, 1:] * b + noise * rng.standard_normal((count, 1)) * n


#: A box-like scene: ground, walls in three directions, slanted roofs (n, d, centre, size).
SCENE = [
    ([0, 0, 1], 1.8, [0, 0, -1.8], 30),
    ([1, 0, 0], 8.0, [-8, 0, 0], 20),
    ([-1, 0, 0], 9.0, [9, 3, 0], 20),
    ([0, 1, 0], 12.0, [2, -12, 0], 15),
    ([0, -1, 0], 15.0, [-3, 15, 0], 15),
    ([0.7, 0.7, 0], 14.0, [-10, -10, 1], 8),
    ([0.3, -0.2, 0.93], -2.0, [4, 4, 3], 5),
    ([-0.5, 0.3, 0.81], -4.0, [-4, 5, 4], 5),
]


def scene_points(rng, count=400):
    return [plane_points(rng, np.array(n, float), d, np.array(c, float), s, count)
            for n, d, c, s in SCENE]  # fmt: skip


def planes_of(sets, rows=20, sigma=1e-4):
    """Planes (normals towards the origin) of point sets, with moments in the support."""
    out = []
    for P in sets:
        c = P.mean(axis=0)
        S = (P - c).T @ (P - c)
        lam, E = np.linalg.eigh(S)
        n = E[:, 0]
        d = -n @ c
        if d < 0:
            n, d = -n, -d
        cov = np.zeros((4, 4))
        cov[:3, :3] = sigma**2 * (np.eye(3) - np.outer(n, n)) / max(lam[1], 1e-9) * len(P) / len(P)
        cov[3, 3] = sigma**2
        out.append(Plane(n, d, cov, 1.0, PlaneSupport(c, np.zeros((0, 3)), len(P), S, rows)))
    return out


def pose(rpy_deg, t):
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", rpy_deg, degrees=True).as_matrix()
    T[:3, 3] = t
    return T
