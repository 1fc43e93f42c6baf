"""Both ends' deskewing errors of a relative-pose factor (planodom.smoothing.relative_deskew):
each end's first-order change of the fitted relative pose against a nonlinear refit
(scipy) of the relative pose from planes moved by their deskewing Jacobians."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import sqrtm
from scipy.optimize import least_squares

from planodom.geometry import Plane, transform_planes
from planodom.se3 import se3_exp, se3_log
from planodom.smoothing.relative_deskew import pair_fit_changes


def _cov(rng: np.random.Generator, n: np.ndarray) -> np.ndarray:
    """A random rank-3 (4, 4) covariance of ``(n, d)``: no variance along ``n`` itself."""
    P = np.eye(4)
    P[:3, :3] -= np.outer(n, n)
    A = rng.normal(size=(4, 4)) * [1e-3, 1e-3, 1e-3, 1e-2]
    return P @ (A @ A.T + 1e-6 * np.eye(4)) @ P


def _jacobian(rng: np.random.Generator, n: np.ndarray) -> np.ndarray:
    """A random (4, 6) deskewing Jacobian that keeps the normal unit."""
    P = np.eye(4)
    P[:3, :3] -= np.outer(n, n)
    return P @ rng.normal(size=(4, 6))


def _epochs(rng: np.random.Generator, T_a_b: np.ndarray) -> tuple[list[Plane], list[Plane]]:
    """Six planes of epoch a and the same seen from b (exactly ``T_a_b``), each with its
    own covariance and deskewing Jacobian."""
    normals = rng.normal(size=(6, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    offsets = rng.uniform(-8.0, 8.0, 6)
    a = [Plane(n, float(d), _cov(rng, n), deskew_jacobian=_jacobian(rng, n))
         for n, d in zip(normals, offsets, strict=True)]  # fmt: skip
    n_b, d_b = transform_planes(np.linalg.inv(T_a_b), normals, offsets)
    b = [Plane(n, float(d), _cov(rng, n), deskew_jacobian=_jacobian(rng, n))
         for n, d in zip(n_b, d_b, strict=True)]  # fmt: skip
    return a, b


def _moved(planes: list[Plane], shift: np.ndarray) -> list[np.ndarray]:
    out = []
    for p in planes:
        c = p.coefficients + p.deskew_jacobian @ shift
        out.append(c / np.linalg.norm(c[:3]))
    return out


def _refit(T_a_b: np.ndarray, a: list[Plane], b: list[Plane], shift_a, shift_b) -> np.ndarray:  # noqa: ANN001
    """(6,) right tangent of the relative pose refitted (nonlinear least squares) to a's
    planes moved by ``shift_a`` and b's by ``shift_b``, weighted by both planes'
    covariances as at ``T_a_b``."""
    ca, cb = _moved(a, shift_a), _moved(b, shift_b)
    roots = []
    for pa, pb in zip(a, b, strict=True):
        J = np.eye(4)
        J[:3, :3], J[3, :3] = T_a_b[:3, :3], -(T_a_b[:3, 3] @ T_a_b[:3, :3])
        W = np.linalg.pinv(pa.covariance + J @ pb.covariance @ J.T, rcond=1e-9, hermitian=True)
        roots.append(np.real(sqrtm(W)))

    def residual(xi: np.ndarray) -> np.ndarray:
        T = T_a_b @ se3_exp(xi)
        out = []
        for x, y, L in zip(ca, cb, roots, strict=True):
            n, d = transform_planes(T, y[None, :3], np.array([y[3]]))
            out.append(L @ (x - np.append(n[0], d[0])))
        return np.concatenate(out)

    return least_squares(residual, np.zeros(6), xtol=1e-15, ftol=1e-15, gtol=1e-15).x


@pytest.mark.parametrize("end", [0, 1])
def test_each_end_is_the_nonlinear_refit(end: int) -> None:
    rng = np.random.default_rng(3 + end)
    T = se3_exp(np.array([0.02, -0.01, 0.4, 1.5, 0.3, 0.05]))
    a, b = _epochs(rng, T)
    pairs = np.column_stack([np.arange(6), np.arange(6)])
    M = pair_fit_changes(T, a, b, pairs)[end]
    assert M is not None and M.shape == (6, 6)
    base = _refit(T, a, b, np.zeros(6), np.zeros(6))
    np.testing.assert_allclose(base, 0.0, atol=1e-9)  # the planes agree with T exactly
    for c, eps in enumerate((2e-5, -3e-5, 1e-5, 4e-5, -2e-5, 3e-5)):
        shift = np.zeros(6)
        shift[c] = eps
        shifts = (shift, np.zeros(6)) if end == 0 else (np.zeros(6), shift)
        xi = se3_log(se3_exp(_refit(T, a, b, *shifts)))
        np.testing.assert_allclose(M[:, c], xi / eps, rtol=2e-3, atol=2e-3 * np.abs(M).max())


def test_an_end_without_jacobians_does_not_move() -> None:
    rng = np.random.default_rng(8)
    T = se3_exp(np.array([0.0, 0.0, 0.3, 1.0, 0.0, 0.0]))
    a, b = _epochs(rng, T)
    still = [Plane(p.normal, p.offset, p.covariance) for p in b]
    pairs = np.column_stack([np.arange(6), np.arange(6)])
    M_a, M_b = pair_fit_changes(T, a, still, pairs)
    assert M_a is not None and M_b is None
    assert pair_fit_changes(T, a, b, np.zeros((0, 2), dtype=int)) == (None, None)
