"""The registration's compiled association and Gauss-Newton against the numpy formulas
they replace (:func:`candidates` with :func:`tie_cost`, :func:`.outliers.whitened` with
the weighted normal equations)."""

from __future__ import annotations

import numpy as np
import pytest
from planemap_factory import pose, scene_points

from planodom.config import PlanemapConfig
from planodom.median import median
from planodom.odometry.planemap.landmarks import PlaneMap
from planodom.odometry.planemap.moments import Moments
from planodom.odometry.planemap.outliers import residual_scale, whitened
from planodom.odometry.planemap.register import (
    ScanPlanes,
    _gauss_newton,
    associate,
    candidates,
    newton_step,
    tie_cost,
)
from planodom.rotvec import rotation_matrices


def _scene(seed: int, noise: float) -> tuple[PlaneMap, ScanPlanes, np.ndarray]:
    """A map of the box scene's planes (world frame, with normal covariances from their
    own scatter), the same planes seen from a pose (scan frame, some split in two, with
    noise) and that pose."""
    rng = np.random.default_rng(seed)
    sets = scene_points(rng, 300)
    # parallel neighbours a few cm off some planes: several landmarks in a plane's gates
    shifted = []
    for P in sets[:5]:
        lam, E = np.linalg.eigh((P - P.mean(0)).T @ (P - P.mean(0)))
        shifted.append(P + rng.uniform(0.01, 0.06) * E[:, 0])
    world = Moments.of_points(sets + shifted, np.full(len(sets) + len(shifted), 12.0))
    M = PlaneMap()
    lam, E = np.linalg.eigh(world.S)
    M.add(world, E[:, :, 0] * np.sign(-np.einsum("ki,ki->k", E[:, :, 0], world.c))[:, None], 0,
          np.arange(len(world)))  # fmt: skip
    M.refit(0.01, 0.002)
    T = pose(rng.uniform(-3, 3, 3), rng.uniform(-0.5, 0.5, 3))
    inv = np.linalg.inv(T)
    parts = []
    for P in sets:  # halves of a wall: two scan planes on one landmark
        P = P @ inv[:3, :3].T + inv[:3, 3] + noise * rng.standard_normal(P.shape)
        parts += [P[:150], P[150:]] if rng.uniform() < 0.4 else [P]
    m = Moments.of_points(parts, np.full(len(parts), 6.0))
    lam, E = np.linalg.eigh(m.S)
    normals = E[:, :, 0] * np.sign(-np.einsum("ki,ki->k", E[:, :, 0], m.c))[:, None]
    return M, ScanPlanes.of(m, normals, 0.01, 0.002), T


@pytest.mark.parametrize("seed", range(8))
def test_compiled_association_picks_what_the_gates_and_ties_pick(seed: int) -> None:
    M, cur, T = _scene(seed, 0.005)
    rng = np.random.default_rng(50 + seed)
    # tight gates near the pose, wide ones farther off (several landmarks gated), tight
    # ones far off (some planes without any)
    seen = []
    for s_r, s_t, off_deg, off_m in ((0.002, 0.01, 0.3, 0.02), (0.05, 0.3, 0.5, 0.05),
                                     (0.002, 0.01, 2.0, 0.2)):  # fmt: skip
        T0 = pose(rng.normal(0, off_deg, 3), rng.normal(0, off_m, 3)) @ T
        cost = tie_cost(candidates(M, T0, cur, s_r, s_t, 0.002), "distance")
        best = np.argmin(cost, axis=1)
        expected = np.where(np.isfinite(cost[np.arange(len(cur)), best]), best, -1)
        got = associate(M, T0, cur, s_r, s_t, 0.002, "distance")
        np.testing.assert_array_equal(got, expected)
        seen.append(got)
    assert (np.concatenate(seen) >= 0).any() and (np.concatenate(seen) < 0).any()


def _numpy_gauss_newton(M, T0, cur, lm, jj, config):
    """The Gauss-Newton loop as numpy formulas (whitened residuals, einsum sums)."""
    R, t = T0[:3, :3].copy(), T0[:3, 3].copy()
    N, c, lam, E = cur.m.N[jj], cur.m.c[jj], cur.lam[jj], cur.E[jj]
    s2 = cur.variances(jj)
    L = max(median(np.linalg.norm(c, axis=1)), 1.0)
    scale = np.r_[np.ones(3), np.full(3, 1.0 / L)]
    for _ in range(config.gn_iterations):
        r, J, v, chi2 = whitened(M, R, t, N, c, lam, E, s2, lm)
        k2 = residual_scale(chi2)
        w = 1.0 / (1.0 + chi2 / (k2 * config.cauchy_scale**2))
        Wr = w[:, None] / (k2 * v)
        H = np.einsum("mk,mki,mkj->ij", Wr, J, J)
        g = np.einsum("mk,mki,mk->i", Wr, J, r)
        dx = newton_step(H, g, scale)
        R = rotation_matrices(dx[:3]) @ R
        t = t + dx[3:]
        if np.linalg.norm(dx[:3]) < 1e-9 and np.linalg.norm(dx[3:]) < 1e-8:
            break
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T, H, w


@pytest.mark.parametrize("seed", range(8))
def test_compiled_gauss_newton_equals_the_numpy_formulas(seed: int) -> None:
    M, cur, T = _scene(seed, 0.005)
    rng = np.random.default_rng(80 + seed)
    T0 = pose(rng.normal(0, 0.3, 3), rng.normal(0, 0.03, 3)) @ T
    lm = associate(M, T0, cur, 0.02, 0.1, 0.002, "distance")
    jj = np.flatnonzero(lm >= 0)
    lm = lm[jj]
    lm[: len(lm) // 5] = (lm[: len(lm) // 5] + 1) % len(M)  # some outliers: Cauchy weights
    config = PlanemapConfig()
    got = _gauss_newton(M, T0, cur, lm, jj, config)
    expected = _numpy_gauss_newton(M, T0, cur, lm, jj, config)
    for a, b in zip(got, expected, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max())
    assert got[2].min() < 0.5 < got[2].max()  # the kernel weighs some down
