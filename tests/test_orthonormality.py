"""``is_orthonormal`` gives numpy's verdict ``max |R^T R - I| <= tol``, bit for bit."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

import planodom.orthonormality as orthonormality
from planodom.geometry import orthonormalised
from planodom.orthonormality import is_orthonormal


def _numpy(R: np.ndarray, tol: float) -> bool:
    """The expression ``orthonormalised`` used before (the oracle)."""
    return bool(np.max(np.abs(R.T @ R - np.eye(3))) <= tol)


def _blocks(rng: np.random.Generator) -> list[np.ndarray]:
    """Rotations, rotations perturbed by 1e-16 .. 1e-3, scaled and random matrices."""
    out: list[np.ndarray] = []
    rots = Rotation.random(400, random_state=rng).as_matrix()
    for k, R in enumerate(rots):
        size = 10.0 ** rng.uniform(-16, -3) if k % 4 else 0.0
        out.append(R + size * rng.standard_normal((3, 3)))
    out += [rng.uniform(-5, 5, (3, 3)) for _ in range(50)]
    out += [3.0 * rots[0], np.zeros((3, 3)), np.eye(3)]
    return out


def test_verdict_equals_numpys_on_random_blocks() -> None:
    rng = np.random.default_rng(11)
    for R in _blocks(rng):
        for tol in (1e-12, 1e-9, 1e-6, 0.0):
            assert is_orthonormal(R, tol) == _numpy(R, tol)


def test_verdict_at_the_tolerance_itself() -> None:
    """Tolerances set to a block's own deviation (and one ulp either side): the guard band,
    where numpy decides."""
    rng = np.random.default_rng(12)
    for R in _blocks(rng)[:200]:
        dev = float(np.max(np.abs(R.T @ R - np.eye(3))))
        for tol in (dev, np.nextafter(dev, 0.0), np.nextafter(dev, 1.0)):
            assert is_orthonormal(R, tol) == _numpy(R, tol)


def test_layouts_and_non_finite_entries() -> None:
    R = Rotation.from_rotvec([0.1, -0.2, 0.3]).as_matrix()
    T = np.eye(4)
    T[:3, :3] = R
    frozen = np.asfortranarray(T)
    frozen.flags.writeable = False
    assert is_orthonormal(frozen[:3, :3], 1e-12) == _numpy(R, 1e-12)
    for bad in (np.nan, np.inf):
        B = R.copy()
        B[1, 2] = bad
        assert is_orthonormal(B, 1e-12) is False
        assert _numpy(B, 1e-12) is False


def test_the_compiled_deviation_decides_away_from_the_band(monkeypatch) -> None:
    """Fails when the compiled deviation is wrong: with no guard band the compiled value
    decides every verdict."""
    monkeypatch.setattr(orthonormality, "_GUARD", 0.0)
    rng = np.random.default_rng(13)
    for R in _blocks(rng):
        dev, _ = orthonormality._deviation(np.ascontiguousarray(R))
        ref = float(np.max(np.abs(R.T @ R - np.eye(3))))
        assert abs(dev - ref) <= 1e-14 * (1.0 + float(np.sum(R * R)))
        for tol in (1e-12, 1e-9, 1e-6):
            assert is_orthonormal(R, tol) == _numpy(R, tol)


def test_orthonormalised_keeps_or_projects() -> None:
    R = Rotation.from_rotvec([0.2, 0.1, -0.4]).as_matrix()
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, [1.0, 2.0, 3.0]
    assert orthonormalised(T) is T
    S = T.copy()
    S[:3, :3] *= 1.0 + 1e-9
    out = orthonormalised(S)
    assert out is not S
    np.testing.assert_allclose(out[:3, :3] @ out[:3, :3].T, np.eye(3), atol=1e-15)
