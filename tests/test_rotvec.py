"""The compiled rotation vectors against scipy's (an independent implementation)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planodom.rotvec import rotation_matrices, rotation_vectors


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


@pytest.mark.parametrize("seed", range(3))
def test_rotation_matrices_equal_scipys_bit_for_bit(seed: int) -> None:
    rng = np.random.default_rng(seed)
    # magnitudes from 1e-12 to 10 rad, both sides of the series' 1e-3, and exact cases
    w = rng.normal(size=(60000, 3))
    w *= (10.0 ** rng.uniform(-12, 1, size=60000) / np.linalg.norm(w, axis=1))[:, None]
    edge = rng.normal(size=(4, 3))
    edge *= (np.array([1e-3, np.nextafter(1e-3, 1), np.nextafter(1e-3, 0), np.pi])
             / np.linalg.norm(edge, axis=1))[:, None]  # fmt: skip
    w = np.vstack([w, edge, np.zeros((1, 3)), [[0.0, -0.0, 1e-300]]])
    np.testing.assert_array_equal(rotation_matrices(w), Rotation.from_rotvec(w).as_matrix())
    for v in w[:200]:  # one vector: (3, 3), as scipy's
        got = rotation_matrices(v)
        assert got.shape == (3, 3)
        assert got.tobytes() == Rotation.from_rotvec(v).as_matrix().tobytes()


def test_rotation_matrices_closed_form() -> None:
    c, s = np.cos(0.7), np.sin(0.7)
    np.testing.assert_allclose(
        rotation_matrices(np.array([0.0, 0.0, 0.7])), [[c, -s, 0], [s, c, 0], [0, 0, 1]],
        atol=1e-15,
    )  # fmt: skip
