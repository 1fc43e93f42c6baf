"""The compiled rotation vectors against scipy's (an independent implementation)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planodom.rotvec import rotation_vectors


@pytest.mark.parametrize("scale", [1e-7, 1e-4, 1e-2, 0.3, 1.0, 3.0, 10.0])
def test_rotation_vectors_equal_scipys_bit_for_bit(scale: float) -> None:
    rng = np.random.default_rng(int(scale * 1e7) % 1000)
    a = Rotation.from_rotvec(rng.normal(size=(2000, 3)) * scale).as_matrix()
    b = Rotation.from_rotvec(rng.normal(size=(2000, 3)) * scale).as_matrix()
    R = a @ b  # products: orthogonal to rounding only, as the odometry's steps
    np.testing.assert_array_equal(rotation_vectors(R), Rotation.from_matrix(R).as_rotvec())


def test_half_turns_identity_and_closed_forms() -> None:
    half_turns = [np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), np.diag([-1.0, -1, 1])]
    R = np.stack([np.eye(3), *half_turns, Rotation.from_rotvec([0.3, 0, 0]).as_matrix()])
    w = rotation_vectors(R)
    expected = [[0, 0, 0], [np.pi, 0, 0], [0, np.pi, 0], [0, 0, np.pi], [0.3, 0, 0]]
    np.testing.assert_allclose(np.abs(w), expected, atol=1e-15)
    np.testing.assert_array_equal(w, Rotation.from_matrix(R).as_rotvec())


def test_non_orthogonal_goes_to_scipy_and_reflection_raises() -> None:
    R = np.stack([np.eye(3) * 1.001, Rotation.from_rotvec([0, 0.2, 0]).as_matrix()])
    np.testing.assert_array_equal(rotation_vectors(R), Rotation.from_matrix(R).as_rotvec())
    with pytest.raises(ValueError, match="determinant"):
        rotation_vectors(np.diag([1.0, 1, -1])[None])
