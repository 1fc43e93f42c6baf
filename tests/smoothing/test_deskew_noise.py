"""The deskewing error's share of the factors' noise (planodom.smoothing.deskew_noise)."""

from __future__ import annotations

import gtsam
import numpy as np
from scipy.spatial.transform import Rotation

from planodom.config import PlanodomConfig
from planodom.odometry.relative import RelativePose
from planodom.smoothing.deskew_noise import DeskewNoise, plane_deskew_covariance
from planodom.smoothing.noise import between_covariance


def _steps(motions: np.ndarray, sigma: float = 1e-9) -> list[RelativePose]:
    """delta = 1 relative poses with the given (rotation vector, translation) motions (K, 6)
    and a declared covariance of ``sigma`` per DoF."""
    out = []
    for k, m in enumerate(motions):
        T = np.eye(4)
        T[:3, :3] = Rotation.from_rotvec(m[:3]).as_matrix()
        T[:3, 3] = m[3:]
        cov = np.eye(5) * sigma**2
        out.append(RelativePose(T, cov, prev=k, curr=k + 1, z_observed=True, sigma_z=sigma))
    return out


def _random_walk_motions(rng: np.random.Generator, n: int, s: np.ndarray) -> np.ndarray:
    """Motions whose changes from one epoch to the next are N(0, s^2) per component."""
    base = np.array([0.0, 0.0, 0.05, 0.5, 0.0, 0.0])
    return base + np.cumsum(rng.normal(0.0, 1.0, (n, 6)) * s, axis=0)


def test_pose_covariance_is_a_third_of_the_motion_change_variance():
    rng = np.random.default_rng(3)
    s = np.array([0.004, 0.002, 0.001, 0.01, 0.005, 0.003])
    model = DeskewNoise()
    for rel in _steps(_random_walk_motions(rng, 3000, s)):
        model.add(rel)
    # Closed form: the twist is off by the change dxi ~ N(0, s^2); E[(t / dt)^2] = 1 / 3.
    expected = s**2 / 3.0
    np.testing.assert_allclose(np.diag(model.pose_covariance()), expected, rtol=0.12)
    # A relative pose over one epoch: dxi_k - dxi_{k-1}, independent changes: twice that.
    np.testing.assert_allclose(np.diag(model.relative_covariance(1)), 2 * expected[:5], rtol=0.12)
    np.testing.assert_allclose(np.diag(model.relative_covariance(3)), 2 * expected[:5], rtol=0.12)


def test_constant_motion_with_declared_noise_gives_no_deskew_term():
    rng = np.random.default_rng(4)
    sigma = 0.002
    motions = np.array([0.0, 0.0, 0.05, 0.5, 0.0, 0.0]) + rng.normal(0.0, sigma, (3000, 6))
    model = DeskewNoise()
    for rel in _steps(motions, sigma):
        model.add(rel)
    # The differences are all odometry noise, which the declared covariances account for.
    assert np.all(np.diag(model.pose_covariance()) < 0.05 * sigma**2)
    assert np.all(np.diag(model.relative_covariance(2)) < 0.1 * sigma**2)


def test_too_few_steps_give_zeros_and_others_are_ignored():
    model = DeskewNoise()
    steps = _steps(_random_walk_motions(np.random.default_rng(5), 4, np.full(6, 0.01)))
    for rel in steps:
        model.add(rel)
    model.add(steps[0].between(0, 2))  # delta = 2: not a step
    assert not np.any(model.pose_covariance())
    assert not np.any(model.relative_covariance(1))


def _perturbed_plane_tangent(n: np.ndarray, d: float, xi: np.ndarray) -> np.ndarray:
    """Tangent (Unit3 basis of n (2), offset (1)) of the plane after its points moved by the
    rigid motion Exp(xi) (p -> R p + t): independent of the first-order formula."""
    R = Rotation.from_rotvec(xi[:3]).as_matrix()
    n2 = R @ n
    d2 = d - n2 @ xi[3:]
    dn = np.asarray(gtsam.Unit3(n).localCoordinates(gtsam.Unit3(n2)))
    return np.append(dn, d2 - d)


def test_plane_deskew_covariance_matches_finite_differences():
    rng = np.random.default_rng(6)
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    d = -3.2
    A = rng.normal(size=(6, 6)) * 1e-3
    pose_cov = A @ A.T
    h = 1e-6
    J = np.stack([_perturbed_plane_tangent(n, d, h * e) / h for e in np.eye(6)], axis=1)  # (3, 6)
    np.testing.assert_allclose(
        plane_deskew_covariance(n, pose_cov), J @ pose_cov @ J.T, rtol=1e-4, atol=1e-14
    )


def test_between_covariance_adds_the_relative_term():
    cfg = PlanodomConfig().smoothing
    model = DeskewNoise()
    steps = _steps(_random_walk_motions(np.random.default_rng(7), 50, np.full(6, 0.01)))
    for rel in steps:
        model.add(rel)
    rel = steps[10]
    added = between_covariance(rel, cfg, model) - between_covariance(rel, cfg)
    np.testing.assert_allclose(added, model.relative_covariance(1), atol=1e-15)
    assert np.all(np.diag(added) > 0)
