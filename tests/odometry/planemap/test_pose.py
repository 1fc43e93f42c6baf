"""The plane map's relative pose: the (roll, pitch, yaw) Jacobian of a rotation."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from planodom.geometry import rpy_from_rotation
from planodom.odometry.planemap.pose import rpy_jacobian


def _one_by_one(R: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """The central differences of one rotation at a time (scipy called per rotation)."""
    J = np.zeros((3, 3))
    for k in range(3):
        w = np.zeros(3)
        w[k] = h
        plus = rpy_from_rotation(Rotation.from_rotvec(w).as_matrix() @ R)
        minus = rpy_from_rotation(Rotation.from_rotvec(-w).as_matrix() @ R)
        J[:, k] = np.angle(np.exp(1j * (plus - minus))) / (2 * h)
    return J


def test_rpy_jacobian_equals_one_rotation_at_a_time_and_the_closed_form():
    """Batched through scipy, the same bits as one call per rotation; and near the
    closed form of d(rpy)/dw (world-frame perturbation: the inverse of the Euler rates'
    matrix) away from gimbal lock."""
    rng = np.random.default_rng(5)
    for _ in range(200):
        R = Rotation.from_rotvec(rng.normal(size=3) * 10 ** rng.uniform(-4, 0.3)).as_matrix()
        J = rpy_jacobian(R)
        assert np.array_equal(J, _one_by_one(R))
        roll, pitch, yaw = rpy_from_rotation(R)
        if abs(np.cos(pitch)) < 0.2:
            continue
        # w = E (roll', pitch', yaw') with R = Rz(yaw) Ry(pitch) Rx(roll)
        cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
        E = np.array([[cy * cp, -sy, 0.0], [sy * cp, cy, 0.0], [-sp, 0.0, 1.0]])
        assert np.allclose(J, np.linalg.inv(E), atol=1e-5)
