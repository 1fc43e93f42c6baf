"""The plane-map fallback's helpers against explicit computations."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from planodom.odometry.planemap.fallback import inverse_rotated


def test_inverse_rotated_is_the_transpose_applied_to_every_normal():
    R = Rotation.random(7, random_state=3).as_matrix()
    n = np.random.default_rng(4).normal(size=(5, 3))
    expected = np.array([[Rc.T @ v for v in n] for Rc in R])
    np.testing.assert_allclose(inverse_rotated(R, n), expected, atol=1e-15)
