"""``se3_exp`` against the former batched expression (bit for bit) and the matrix exponential."""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

from planodom.se3 import se3_exp


def _former_se3_exp(xi: np.ndarray) -> np.ndarray:
    """``se3_exp`` as it was before the one-twist path (both branches through np.where)."""
    xi = np.asarray(xi, dtype=np.float64)
    flat = xi.reshape(-1, 6)
    w, v = flat[:, :3], flat[:, 3:]
    th = np.linalg.norm(w, axis=1)
    small = th < 1e-3
    ths = np.where(small, 1.0, th)
    t2 = th**2
    a = np.where(small, 1.0 - t2 / 6.0 + t2**2 / 120.0, np.sin(ths) / ths)
    b = np.where(small, 0.5 - t2 / 24.0 + t2**2 / 720.0, (1.0 - np.cos(ths)) / ths**2)
    c = np.where(small, 1.0 / 6.0 - t2 / 120.0 + t2**2 / 5040.0, (ths - np.sin(ths)) / ths**3)
    K = np.zeros((len(w), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    K = K - np.swapaxes(K, 1, 2)
    K2 = K @ K
    eye = np.eye(3)
    out = np.zeros((len(flat), 4, 4))
    out[:, :3, :3] = eye + a[:, None, None] * K + b[:, None, None] * K2
    V = eye + b[:, None, None] * K + c[:, None, None] * K2
    out[:, :3, 3] = np.einsum("tij,tj->ti", V, v)
    out[:, 3, 3] = 1.0
    return out.reshape(xi.shape[:-1] + (4, 4))


def _twists(rng: np.random.Generator) -> np.ndarray:
    """(N, 6) twists with angles from 0 and 1e-9 rad across the series' 1e-3 to 3 rad."""
    xi = rng.standard_normal((400, 6))
    xi[:, :3] *= (10.0 ** rng.uniform(-9, 0.5, 400))[:, None]
    xi[:5, :3] = 0.0
    xi[5] = [1e-3, 0.0, 0.0, 1.0, 2.0, 3.0]  # at the switch
    xi[6] = [np.nextafter(1e-3, 0.0), 0.0, 0.0, 1.0, 2.0, 3.0]
    return xi


def test_one_twist_equals_the_former_expression_bit_for_bit() -> None:
    rng = np.random.default_rng(21)
    for x in _twists(rng):
        np.testing.assert_array_equal(se3_exp(x), _former_se3_exp(x))
        np.testing.assert_array_equal(se3_exp(x[None]), _former_se3_exp(x[None]))


def test_batches_and_non_finite_twists_equal_the_former_expression() -> None:
    rng = np.random.default_rng(22)
    xi = _twists(rng)
    np.testing.assert_array_equal(se3_exp(xi), _former_se3_exp(xi))
    np.testing.assert_array_equal(
        se3_exp(xi[:12].reshape(3, 4, 6)), _former_se3_exp(xi[:12].reshape(3, 4, 6))
    )
    bad = np.array([np.nan, 0.1, 0.0, 1.0, 0.0, 0.0])
    np.testing.assert_array_equal(se3_exp(bad), _former_se3_exp(bad))  # NaN in the same places


def test_against_the_matrix_exponential() -> None:
    """An independent computation: scipy's expm of the twist's 4 x 4 generator."""
    rng = np.random.default_rng(23)
    for x in _twists(rng)[::7]:
        G = np.zeros((4, 4))
        G[:3, :3] = [[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]]
        G[:3, 3] = x[3:]
        np.testing.assert_allclose(se3_exp(x), expm(G), rtol=0, atol=1e-12)


def test_compiled_path_gives_the_former_bytes_signed_zeros_included() -> None:
    """The compiled path (series and closed form) against the former numpy expression,
    bytes compared (a zero's sign too): twists of 1e-9 to 4 rad with components set to +0
    and -0, one at a time and in batches mixing both branches."""
    rng = np.random.default_rng(24)
    for trial in range(3000):
        n = 1 if trial % 3 else int(rng.integers(2, 6))
        xi = rng.standard_normal((n, 6)) * 10.0 ** rng.uniform(-9, 0.3, (n, 1))
        xi[rng.random((n, 6)) < 0.3] = 0.0
        xi[rng.random((n, 6)) < 0.2] = -0.0
        x = xi[0] if n == 1 else xi
        assert se3_exp(x).tobytes() == _former_se3_exp(x).tobytes()


def test_a_read_only_twist_reaches_the_kernel_writeable(monkeypatch) -> None:
    """numba compiles a read-only array as another type: a read-only twist (a cached
    prediction's) must not compile the kernel a second time in the middle of a run."""
    import planodom.se3 as se3

    seen: list[np.ndarray] = []
    kernel = se3._se3_exp_kernel

    def spy(flat, cube):  # type: ignore[no-untyped-def]
        seen.append(flat)
        return kernel(flat, cube)

    monkeypatch.setattr(se3, "_se3_exp_kernel", spy)
    x = np.array([0.1, 0.2, 0.3, 1.0, 2.0, 3.0])
    x.flags.writeable = False
    se3_exp(x)
    assert seen and all(f.flags.writeable and f.flags.c_contiguous for f in seen)
