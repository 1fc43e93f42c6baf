"""Marginals (Hessians) as Jacobian factors, and the windowed smoother's QR fallback on them."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from planodom.smoothing.graph import X
from planodom.smoothing.jacobian_marginal import (
    ROUND_OFF_EPS,
    jacobian_from_information,
    jacobian_marginal,
    split_information,
)
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


def schur_marginal(stiff: float = 1e12, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(6, 6) marginal information of a pose ``x`` after eliminating a pose ``y`` that only
    a stiff relative factor (``stiff``, as plane factors at their floors) ties to it, the
    Schur complement formed as iSAM2's Cholesky does; ``x`` has a weak prior (1) on 5 of
    its 6 directions, and the (6, 6) exact marginal (that prior: the stiff factor
    marginalises out exactly, ``y`` being observed by nothing else)."""
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.standard_normal((6, 6)))
    prior = Q[:, :5] @ Q[:, :5].T  # eigenvalues 1, 1, 1, 1, 1, 0
    R = np.linalg.qr(rng.standard_normal((6, 6)))[0] * np.sqrt(stiff)  # the stiff factor's
    J = np.hstack([R, -R @ np.diag(1.0 + rng.random(6))])  # Jacobian on (x, y)
    H = J.T @ J
    H[:6, :6] += prior
    L = np.linalg.cholesky(H[6:, 6:])
    W = np.linalg.solve(L, H[6:, :6])
    S = H[:6, :6] - W.T @ W
    # The sign of the round-off along the unobserved direction depends on the CPU and
    # BLAS (negative on some machines, positive on others): set it to a negative value of
    # the size elimination leaves (stiff * eps), so that the case is the same everywhere.
    w, V = np.linalg.eigh(S)
    null = V[:, 0]
    S -= (w[0] + 0.7 * stiff * np.finfo(float).eps) * np.outer(null, null)
    return S, prior


def test_a_marginal_indefinite_by_its_eliminated_round_off_is_split() -> None:
    """WINDCRASH: the round-off of a Schur complement is ``eps`` times the information
    eliminated into it (1e12 here, 2e-4), not times its own largest eigenvalue (1): main
    refused it ("indefinite beyond round-off") and stopped the fixed-lag smoother's QR
    fallback (worlds 6 and 10 of the 2D-rig laps at 6 mm). The split keeps the observed
    directions (the exact marginal's, to the round-off) and reports the indefiniteness."""
    G, exact = schur_marginal()
    w = np.linalg.eigvalsh(G)
    tol = ROUND_OFF_EPS * 6 * np.finfo(float).eps * w[-1]
    assert w[0] < -10 * tol  # the case: indefinite far beyond the marginal's own round-off
    g = exact @ np.arange(1.0, 7.0)  # in the exact marginal's range
    split = split_information(G, g)
    assert split.A.shape == (5, 6)
    assert split.indefinite == pytest.approx(-w[0] / w[-1])
    round_off = 1e-3  # 1e12 * eps = 2.2e-4, times a few
    np.testing.assert_allclose(split.A.T @ split.A, exact, atol=round_off)
    np.testing.assert_allclose(split.A.T @ split.b, g, atol=round_off * np.abs(g).max())
    # within the marginal's own round-off nothing is reported
    assert split_information(*stiff_marginal()).indefinite == 0.0


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


def test_qr_fallback_takes_and_reports_an_indefinite_marginal() -> None:
    """The fallback rebuilds from a held marginal indefinite by its eliminated round-off
    (main: ValueError, the run stopped): the estimate is the minimum of the exact marginal
    and the priors, and the smoother reports the indefiniteness."""
    (G0, exact0), (G1, exact1) = schur_marginal(seed=0), schur_marginal(seed=3)
    G = np.block([[G0, np.zeros((6, 6))], [np.zeros((6, 6)), G1]])
    exact = np.block([[exact0, np.zeros((6, 6))], [np.zeros((6, 6)), exact1]])
    g = exact @ np.linspace(-1e-3, 1e-3, 12)  # in the exact marginal's range
    point = gtsam.Values()
    point.insert(X(0), gtsam.Pose3())
    point.insert(X(1), gtsam.Pose3())
    smoother = WindowedSmoother()
    factors = gtsam.NonlinearFactorGraph()
    prior = gtsam.noiseModel.Isotropic.Sigma(6, 1.0)  # as weak as the marginal
    factors.add(gtsam.PriorFactorPose3(X(0), gtsam.Pose3(), prior))
    factors.add(gtsam.PriorFactorPose3(X(1), gtsam.Pose3(), prior))
    factors.add(hessian_container(G, g, point))
    smoother.smoother = gtsam.IncrementalFixedLagSmoother(smoother.lag, smoother._isam_params())
    smoother.smoother.update(factors, point, {X(0): 0.0, X(1): 0.0})  # type: ignore[arg-type]
    smoother._fall_back_to_qr()
    assert smoother.factorization == "QR"
    w = np.linalg.eigvalsh(G)  # one held marginal: its most negative over its largest
    worst = -w[0] / w[-1]
    assert smoother.indefinite_marginals == [(-1, pytest.approx(worst))]
    assert smoother.qr_fallback_epochs == [-1]  # no epoch added
    estimate = smoother.smoother.calculateEstimate()
    delta = np.concatenate(
        [gtsam.Pose3.Logmap(estimate.atPose3(X(0))), gtsam.Pose3.Logmap(estimate.atPose3(X(1)))]
    )
    expected = np.linalg.solve(exact + np.eye(12), g)  # priors at the point
    np.testing.assert_allclose(delta, expected, atol=1e-3 * np.abs(expected).max())
