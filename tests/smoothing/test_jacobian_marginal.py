"""Marginals (Hessians) as Jacobian factors, and the windowed smoother's QR fallback on them."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from planodom.smoothing.graph import X
from planodom.smoothing.jacobian_marginal import jacobian_from_information, jacobian_marginal
from planodom.smoothing.windowed import WindowedSmoother


def stiff_marginal(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(12, 12) information of two poses observing 6 of their 12 directions, to 1e14 as
    plane factors at their floors do, with round-off of -0.03 along an unobserved one (as
    urban-canyon's marginal at epoch 395), and the (12,) information vector of a point in
    its range."""
    rng = np.random.default_rng(seed)
    J = 1e7 * rng.standard_normal((6, 12))
    G = J.T @ J
    _, _, Vt = np.linalg.svd(J)
    null = Vt[-1]
    G = G - 0.03 * np.outer(null, null)
    delta = J.T @ rng.standard_normal(6) * 1e-9  # in G's range
    return G, G @ delta


def test_jacobian_reproduces_the_information_on_its_range() -> None:
    G, g = stiff_marginal()
    A, b = jacobian_from_information(G, g)
    assert A.shape == (6, 12) and b.shape == (6,)
    w, V = np.linalg.eigh(G)
    observed = V[:, w > 1.0]  # the six observed directions (eigenvalues ~1e13..1e15)
    P = observed @ observed.T
    np.testing.assert_allclose(A.T @ A, P @ G @ P, atol=1e-12 * np.abs(G).max())
    np.testing.assert_allclose(A.T @ b, g, atol=1e-9 * np.abs(g).max())


def test_indefinite_beyond_round_off_is_refused() -> None:
    G = np.diag([1.0, 2.0, -0.5])
    with pytest.raises(ValueError, match="indefinite"):
        jacobian_from_information(G, np.zeros(3))


def hessian_container(
    G: np.ndarray, g: np.ndarray, point: gtsam.Values
) -> gtsam.LinearContainerFactor:
    """A marginal of X(0), X(1) as iSAM2 with Cholesky keeps it (information form)."""
    hessian = gtsam.HessianFactor(X(0), X(1), G[:6, :6], G[:6, 6:], g[:6], G[6:, 6:], g[6:], 0.0)
    return gtsam.LinearContainerFactor(hessian, point)


def test_jacobian_marginal_has_the_containers_error() -> None:
    G, g = stiff_marginal(1)
    point = gtsam.Values()
    point.insert(X(0), gtsam.Pose3())
    point.insert(X(1), gtsam.Pose3(gtsam.Rot3.Yaw(0.3), np.array([1.0, 0.0, 0.0])))
    factor = jacobian_marginal(hessian_container(G, g, point), point)
    moved = gtsam.Values()
    delta = np.random.default_rng(2).standard_normal(12) * 1e-6
    moved.insert(X(0), point.atPose3(X(0)).retract(delta[:6]))
    moved.insert(X(1), point.atPose3(X(1)).retract(delta[6:]))
    A, rhs = (np.asarray(m) for m in factor.linearize(moved).jacobian())
    # the gradient at delta, -A^T rhs, is the quadratic form's, G delta - g, but along
    # the direction G leaves unobserved (its round-off dropped)
    w, V = np.linalg.eigh(G)
    P = V[:, w > 1.0] @ V[:, w > 1.0].T
    expected = P @ (G @ delta - g)
    np.testing.assert_allclose(-A.T @ rhs.ravel(), expected, atol=1e-9 * np.abs(expected).max())


def test_qr_fallback_takes_a_marginal_with_round_off() -> None:
    """Cholesky fails on the update; main rebuilt the smoother with QR through gtsam's
    Hessian -> Jacobian conversion, which refuses the round-off too. The rebuilt
    smoother's estimate is the minimum of the marginal and the priors that fix what it
    leaves unobserved."""
    G, g = stiff_marginal(3)
    point = gtsam.Values()
    point.insert(X(0), gtsam.Pose3())
    point.insert(X(1), gtsam.Pose3())
    smoother = WindowedSmoother()
    factors = gtsam.NonlinearFactorGraph()
    prior = gtsam.noiseModel.Isotropic.Sigma(6, 1e-3)
    factors.add(gtsam.PriorFactorPose3(X(0), gtsam.Pose3(), prior))
    factors.add(gtsam.PriorFactorPose3(X(1), gtsam.Pose3(), prior))
    factors.add(hessian_container(G, g, point))
    smoother.smoother = gtsam.IncrementalFixedLagSmoother(smoother.lag, smoother._isam_params())
    with pytest.raises(RuntimeError, match="Indeterminate"):  # Cholesky, as on urban-canyon
        smoother.smoother.update(factors, point, {X(0): 0.0, X(1): 0.0})  # type: ignore[arg-type]
    smoother._fall_back_to_qr()  # main: IndeterminantLinearSystemException
    assert smoother.factorization == "QR"
    estimate = smoother.smoother.calculateEstimate()
    delta = np.concatenate(
        [gtsam.Pose3.Logmap(estimate.atPose3(X(0))), gtsam.Pose3.Logmap(estimate.atPose3(X(1)))]
    )
    expected = np.linalg.solve(G + 1e6 * np.eye(12), g)  # priors at the point, sigma 1e-3
    np.testing.assert_allclose(delta, expected, rtol=1e-5, atol=1e-9)
