"""The continuous-time registration against explicit point sums and a known motion."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planodom.extraction.deskew import deskew_points
from planodom.extraction.planes.builder import time_moments
from planodom.geometry import invert_transform, se3_exp, transform_points
from planodom.odometry.planemap.ctreg import corrected_moments, ct_cost, register_twist, stacked
from planodom.odometry.planemap.landmarks import PlaneMap
from planodom.odometry.planemap.moments import Moments
from planodom.odometry.planemap.register import Registration, ScanPlanes


def _random_pose(rng, ang=0.3, tr=2.0):
    return Rotation.from_rotvec(rng.uniform(-ang, ang, 3)).as_matrix(), rng.uniform(-tr, tr, 3)


def _unit(rng, k=None):
    n = rng.normal(size=3 if k is None else (k, 3))
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


@pytest.mark.parametrize("order", [1, 2])
def test_cost_equals_point_sum(order):
    """The moments' cost is the explicit sum over the points moved by the correction."""
    rng = np.random.default_rng(0)
    for _ in range(10):
        P = rng.normal(size=(60, 3)) * [3, 2, 0.1] + rng.normal(size=3) * 10
        tau = rng.uniform(-0.05, 0.05, len(P))
        c = P.mean(axis=0)
        M = time_moments(P, tau, c)
        R, t = _random_pose(rng)
        n, d = _unit(rng), rng.normal() * 5
        x = rng.normal(size=6 * order) * np.tile([0.5, 0.5, 0.5, 2, 2, 2], order)
        w, v = x[:3], x[3:6]
        moved = P + tau[:, None] * (np.cross(w, P) + v)
        if order == 2:
            moved += 0.5 * tau[:, None] ** 2 * (np.cross(x[6:9], P) + x[9:12])
        explicit = np.sum((moved @ R.T @ n + t @ n + d) ** 2)
        assert ct_cost(R, t, n, d, c, M, x) == pytest.approx(explicit, rel=1e-9)


@pytest.mark.parametrize("order", [1, 2])
def test_jacobian_matches_finite_differences(order):
    rng = np.random.default_rng(1)
    m = 5
    n, d, c = _unit(rng, m), rng.normal(size=m), rng.normal(size=(m, 3)) * 6
    R, t = _random_pose(rng)
    x = rng.normal(size=6 * order)
    _, J = stacked(R, t, n, d, c, x)
    h = 1e-6
    exp = Rotation.from_rotvec
    for k in range(J.shape[2]):
        dx = np.zeros(J.shape[2])
        dx[k] = h
        zp, _ = stacked(exp(dx[:3]).as_matrix() @ R, t + dx[3:6], n, d, c, x + dx[6:])
        zm, _ = stacked(exp(-dx[:3]).as_matrix() @ R, t - dx[3:6], n, d, c, x - dx[6:])
        np.testing.assert_allclose((zp - zm) / (2 * h), J[:, :, k], rtol=1e-5, atol=1e-6)


def _room():
    """World planes (n, d) of a room seen from inside, with 2D frames to sample them."""
    normals = np.array(
        [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1],
         [0.6, 0.8, 0], [0.8, 0, 0.6]], dtype=float,
    )  # fmt: skip
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    offsets = np.array([6.0, 7.0, 5.0, 8.0, 1.5, 3.0, 6.5, 5.5])
    return normals, offsets


def _points_on(n, d, rng, k, half=3.0):
    a = np.cross(n, [0.3, 0.5, 0.8])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    uv = rng.uniform(-half, half, (k, 2))
    return -d * n + uv[:, :1] * a + uv[:, 1:] * b


def _scan(T_true, xi_true, xi_used, rng, sigma=0.0):
    """Planes of a scan of the room (pose ``T_true`` at the reference time, true constant
    twist ``xi_true``), seen over a sweep of 0.1 s (time by azimuth) and deskewed with
    ``xi_used``: their moments, normals and time moments (scan frame)."""
    normals, offsets = _room()
    sets, taus = [], []
    for n, d in zip(normals, offsets, strict=True):
        X = _points_on(n, d, rng, 400)
        p_ref = transform_points(invert_transform(T_true), X)  # true base frame, ref time
        tau = np.arctan2(p_ref[:, 1], p_ref[:, 0]) / np.pi * 0.05
        tau += rng.uniform(-0.004, 0.004, len(tau))  # several lasers, a column's spread
        # raw point at its own time: p_ref = exp(tau xi) q
        q = np.einsum("mij,mj->mi", se3_exp(-tau[:, None] * xi_true)[:, :3, :3], p_ref)
        q += se3_exp(-tau[:, None] * xi_true)[:, :3, 3]
        q += rng.normal(size=q.shape) * sigma
        sets.append(deskew_points(q, tau, xi_used))
        taus.append(tau)
    m = Moments.of_points(sets, rows=np.full(len(sets), 16.0))
    tm = np.array([time_moments(p, tau, p.mean(axis=0)) for p, tau in zip(sets, taus, strict=True)])
    R = T_true[:3, :3]
    return m, normals @ R, tm


def _map():
    normals, offsets = _room()
    rng = np.random.default_rng(7)
    sets = [_points_on(n, d, rng, 2000) for n, d in zip(normals, offsets, strict=True)]
    m = Moments.of_points(sets)
    M = PlaneMap()
    M.add(m, normals, 0, np.arange(len(m)))
    M.refit(0.001, 0.0)
    return M


@pytest.mark.parametrize("order", [1, 2])
def test_recovers_pose_and_twist(order):
    """A scan of known planes taken under a known twist, deskewed with a wrong one: the
    registration from a perturbed pose recovers the pose and the twist (extracted again
    with the corrected twist, as the odometry does, to undo the first-order model)."""
    rng = np.random.default_rng(3)
    M = _map()
    T_true = se3_exp(np.array([0.05, -0.03, 0.4, 0.3, -0.2, 0.1]))
    xi_true = np.array([0.1, -0.05, 1.2, 1.5, 0.2, 0.05])
    used = xi_true + np.array([0.05, 0.04, -0.8, -0.6, 0.3, 0.1])  # 46 deg/s off in yaw
    T0 = T_true @ se3_exp(np.array([0.002, -0.001, 0.003, 0.01, 0.02, -0.01]))
    first_error = np.linalg.norm(used - xi_true)
    for _ in range(4):  # the first-order model: about 100x closer per extraction
        m, normals, tm = _scan(T_true, xi_true, used, rng)
        cur = ScanPlanes.of(m, normals, 0.001, 0.0)
        reg = Registration(T0, np.eye(6), np.arange(len(m)), np.arange(len(m)),
                           np.ones(len(m)), "map")  # fmt: skip
        prior = np.full(6 * order, 10.0)
        got = register_twist(M, reg, cur, tm, prior, 10)
        assert got is not None
        used = used + got.correction
        T0 = got.T
    np.testing.assert_allclose(used, xi_true, atol=1e-6 * first_error)
    np.testing.assert_allclose(T0, T_true, atol=1e-7)


def test_prior_keeps_an_unobserved_correction():
    """A correction the planes do not observe stays at the prior's mean (zero)."""
    rng = np.random.default_rng(4)
    M = _map()
    T_true = np.eye(4)
    xi = np.array([0.0, 0.0, 0.5, 1.0, 0.0, 0.0])
    m, normals, tm = _scan(T_true, xi, xi, rng)
    cur = ScanPlanes.of(m, normals, 0.001, 0.0)
    reg = Registration(T_true, np.eye(6), np.arange(len(m)), np.arange(len(m)),
                       np.ones(len(m)), "map")  # fmt: skip
    got = register_twist(M, reg, cur, tm, np.full(6, 1e-9), 5)
    assert got is not None
    np.testing.assert_allclose(got.correction, 0.0, atol=1e-12)
    np.testing.assert_allclose(got.T, T_true, atol=1e-9)


@pytest.mark.parametrize("order", [1, 2])
def test_corrected_moments_are_those_of_the_moved_points(order):
    rng = np.random.default_rng(5)
    sets = [rng.normal(size=(80, 3)) * [3, 2, 0.1] + rng.normal(size=3) * 10 for _ in range(4)]
    taus = [rng.uniform(-0.05, 0.05, 80) for _ in sets]
    c = np.array([p.mean(axis=0) for p in sets])
    tm = np.array([time_moments(p, t, ci) for p, t, ci in zip(sets, taus, c, strict=True)])
    x = rng.normal(size=6 * order)
    N, cx, S = corrected_moments(c, tm, x)
    moved = []
    for p, t in zip(sets, taus, strict=True):
        q = p + t[:, None] * (np.cross(x[:3], p) + x[3:6])
        if order == 2:
            q += 0.5 * t[:, None] ** 2 * (np.cross(x[6:9], p) + x[9:12])
        moved.append(q)
    want = Moments.of_points(moved)
    np.testing.assert_allclose(N, want.N)
    np.testing.assert_allclose(cx, want.c, atol=1e-10)
    np.testing.assert_allclose(S, want.S, rtol=1e-9, atol=1e-9)


def test_twist_estimation_switches_on_time_moments():
    from planodom.config import PlanodomConfig

    assert not PlanodomConfig().extraction.time_moments
    on = PlanodomConfig.model_validate({"planemap": {"twist_estimation": "registered"}})
    assert on.extraction.time_moments and not on.extraction.deskew_jacobian
