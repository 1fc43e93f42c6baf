"""The moment cost of the plane-map odometry against explicit point sums."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planodom.odometry.planemap.moments import (
    Moments,
    merge_moments,
    moment_residuals,
    p2p_cost_moments,
    p2p_cost_points,
)


def _random_pose(rng, ang=0.3, tr=2.0):
    return Rotation.from_rotvec(rng.uniform(-ang, ang, 3)).as_matrix(), rng.uniform(-tr, tr, 3)


def test_moment_cost_equals_point_sum():
    rng = np.random.default_rng(0)
    for _ in range(20):
        P = rng.normal(size=(50, 3)) * [3, 2, 0.1] + rng.normal(size=3) * 10
        m = Moments.of_points([P])
        R, t = _random_pose(rng)
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        d = rng.normal() * 5
        explicit = p2p_cost_points(R, t, n, d, P)
        assert p2p_cost_moments(R, t, n, d, m.N[0], m.c[0], m.S[0]) == pytest.approx(
            explicit, rel=1e-10
        )
        lam, E = np.linalg.eigh(m.S)
        r, _, _ = moment_residuals(R, t, n[None], np.array([d]), m.N, m.c, lam, E)
        assert np.sum(r**2) == pytest.approx(explicit, rel=1e-10)


def test_merged_moments_are_the_union():
    rng = np.random.default_rng(1)
    A, B = rng.normal(size=(30, 3)) + 4, rng.normal(size=(70, 3)) * 2
    ma, mb, mab = Moments.of_points([A]), Moments.of_points([B]), Moments.of_points([np.r_[A, B]])
    N, c, S = merge_moments(ma.N[0], ma.c[0], ma.S[0], mb.N[0], mb.c[0], mb.S[0])
    assert N == mab.N[0]
    np.testing.assert_allclose(c, mab.c[0], atol=1e-12)
    np.testing.assert_allclose(S, mab.S[0], atol=1e-9)


def test_jacobians_match_finite_differences():
    rng = np.random.default_rng(2)
    m = Moments.of_points(
        [rng.normal(size=(40, 3)) * [2, 1, 0.05] + rng.normal(size=3) * 8 for _ in range(5)]
    )
    lam, E = np.linalg.eigh(m.S)
    n = rng.normal(size=(5, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    d = rng.normal(size=5)
    R, t = _random_pose(rng)
    _, J, _ = moment_residuals(R, t, n, d, m.N, m.c, lam, E)
    h = 1e-6
    for k in range(6):
        dx = np.zeros(6)
        dx[k] = h
        exp = Rotation.from_rotvec
        rp, _, _ = moment_residuals(exp(dx[:3]).as_matrix() @ R, t + dx[3:], n, d, m.N, m.c, lam, E)
        rm, _, _ = moment_residuals(
            exp(-dx[:3]).as_matrix() @ R, t - dx[3:], n, d, m.N, m.c, lam, E
        )
        np.testing.assert_allclose((rp - rm) / (2 * h), J[:, :, k], rtol=1e-5, atol=1e-6)


def test_normal_equations_equal_point_to_plane_icp():
    """H and g of the four moment residuals are those of point-to-plane ICP over all points."""
    rng = np.random.default_rng(3)
    P = rng.normal(size=(200, 3)) * [4, 2, 0.2] + [5, -3, 1]
    m = Moments.of_points([P])
    lam, E = np.linalg.eigh(m.S)
    n = np.array([0.2, 0.1, 1.0]) / np.linalg.norm([0.2, 0.1, 1.0])
    d = -0.7
    R, t = _random_pose(rng)
    r, J, _ = moment_residuals(R, t, n[None], np.array([d]), m.N, m.c, lam, E)
    q = P @ R.T
    rp = (q + t) @ n + d
    Jp = np.concatenate([np.cross(q, n), np.tile(n, (len(P), 1))], axis=1)
    np.testing.assert_allclose(J[0].T @ J[0], Jp.T @ Jp, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(J[0].T @ r[0], Jp.T @ rp, rtol=1e-9, atol=1e-9)
