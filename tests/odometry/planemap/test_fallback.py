"""The plane-map fallback's helpers against explicit computations."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from planodom.odometry.planemap.fallback import rotation_wocsc
from planodom.planes import PlaneSet


def _planes(normals: np.ndarray) -> PlaneSet:
    """Planes with these unit normals (K, 3), equal normal covariances (1e-6 rad^2 per
    axis), other fields unused by the rotation."""
    k = len(normals)
    cov = np.zeros((k, 4, 4))
    cov[:, :3, :3] = np.eye(3) * 1e-6
    return PlaneSet(normals, np.zeros(k), np.ones(k), np.zeros((k, 3)), np.ones(k), cov)


def test_rotation_wocsc_recovers_the_rotation_and_flags_a_wrong_association():
    """``n_prev = R n_curr`` for six associations and one wrong one: the WOCSC rotation
    (compiled consensus) is ``R`` to rounding, the wrong association its only outlier."""
    rng = np.random.default_rng(5)
    n_p = rng.normal(size=(7, 3))
    n_p /= np.linalg.norm(n_p, axis=1, keepdims=True)
    R = Rotation.from_rotvec([0.05, -0.02, 0.3]).as_matrix()
    n_c = n_p @ R  # rows R^T n_p
    n_c[6] = Rotation.from_rotvec([0.0, 0.6, 0.0]).apply(n_c[6])  # wrong by 34 deg
    ij = np.column_stack([np.arange(7), np.arange(7)])
    R_est, inliers = rotation_wocsc(_planes(n_p), _planes(n_c), ij, np.radians(2.0))
    assert R_est is not None and inliers is not None
    np.testing.assert_allclose(R_est, R, atol=1e-12)
    np.testing.assert_array_equal(inliers, [True] * 6 + [False])
