"""The laser bias fitted to the registration's residuals (``planemap.laser_bias: fitted``)
and the deskewing error's share of the residual variances (``planemap.deskew_variance``)."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from planemap_factory import plane_points

from planodom.config import PlanodomConfig
from planodom.extraction.planes.fit import deskew_jacobian, tls_fit
from planodom.odometry.planemap.bias import fitted_bias, variance_parts
from planodom.odometry.planemap.landmarks import PlaneMap, update_map
from planodom.odometry.planemap.moments import Moments, moment_residuals
from planodom.odometry.planemap.outliers import whitened
from planodom.odometry.planemap.register import ScanPlanes, deskew_variances

SIGMA = 0.003  # point noise, m
ROWS = 16  # scan lines per plane
PER_LINE = 100  # points per line


def _scene(seed: int, K: int = 40) -> list[tuple[np.ndarray, float, np.ndarray]]:
    """K planes (normal, offset, centre) around the origin, facing it."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(K):
        centre = rng.uniform(-15, 15, 3)
        n = -centre / np.linalg.norm(centre) + 0.3 * rng.standard_normal(3)
        n /= np.linalg.norm(n)
        out.append((n, float(-n @ centre), centre))
    return out


def _scan(scene, seed: int, bias_m: float) -> tuple[Moments, np.ndarray]:
    """Moments and normals of the planes seen once: each over ROWS lines (parallel
    strips across it), every line offset along the normal by its own bias drawn with
    sigma ``bias_m``."""
    rng = np.random.default_rng(seed)
    sets = []
    for n, d, centre in scene:
        P = plane_points(rng, n, d, centre, 4.0, ROWS * PER_LINE, noise=SIGMA)
        across = np.cross(n, [0.0, 0.0, 1.0])
        s = (P - P.mean(axis=0)) @ (across / np.linalg.norm(across))
        line = np.minimum(((s - s.min()) / np.ptp(s) * ROWS).astype(int), ROWS - 1)
        sets.append(P + rng.normal(0.0, bias_m, ROWS)[line, None] * n)
    m = Moments.of_points(sets, rows=np.full(len(sets), float(ROWS)))
    normals = np.array([n for n, _, _ in scene])
    return m, normals


def _map(scene, bias_m: float, refit_bias_m: float) -> PlaneMap:
    m, normals = _scan(scene, 1, bias_m)
    M = PlaneMap()
    none = np.full(len(m), -1)
    update_map(M, np.eye(4), m, normals, none, np.zeros(len(m)), 0, np.arange(len(m)), SIGMA,
               PlanodomConfig().planemap, refit_bias_m)  # fmt: skip
    assert len(M) == len(scene)
    return M


@pytest.mark.parametrize("bias_m", [0.0, 0.004, 0.012])
def test_the_fitted_bias_is_the_lines_own(bias_m: float) -> None:
    scene = _scene(3)
    M = _map(scene, bias_m, 0.02)  # the map refit with another bias: it is taken out again
    m, normals = _scan(scene, 2, bias_m)
    cur = ScanPlanes.of(m, normals, SIGMA, 0.02)
    idx = np.arange(len(scene))
    fitted = fitted_bias(M, np.eye(4), cur, idx, idx, 0.05)
    assert fitted is not None
    # 40 planes: the median's spread is about a fifth; without bias the point noise alone
    # (3 mm) explains the residuals
    assert fitted == pytest.approx(bias_m, abs=0.25 * bias_m + 0.0005)


def test_the_fitted_bias_stays_within_its_bound_and_needs_associations() -> None:
    scene = _scene(4)
    M = _map(scene, 0.03, 0.02)
    m, normals = _scan(scene, 2, 0.03)
    cur = ScanPlanes.of(m, normals, SIGMA, 0.02)
    idx = np.arange(len(scene))
    assert fitted_bias(M, np.eye(4), cur, idx, idx, 0.01) == 0.01
    assert fitted_bias(M, np.eye(4), cur, idx[:5], idx[:5], 0.05) is None


@pytest.mark.parametrize("deskew", [False, True])
def test_variance_parts_are_the_registrations_variances_at_any_bias(deskew: bool) -> None:
    """``A + b^2 B`` equals the registration's own variances (:func:`whitened`) of the map
    and scan planes refit with that bias, from a map refit with another one."""
    scene = _scene(5, 12)
    M = _map(scene, 0.01, 0.01)
    m, normals = _scan(scene, 2, 0.01)
    rng = np.random.default_rng(6)
    cov = None
    if deskew:
        L = 1e-3 * rng.standard_normal((len(m), 4, 4))
        cov = L @ np.swapaxes(L, 1, 2)
    T = np.eye(4)
    T[:3, 3] = [0.01, -0.02, 0.005]
    idx = np.arange(len(scene))
    for b in (0.0, 0.004, 0.03):
        cur = ScanPlanes.of(m, normals, SIGMA, b, cov)
        r, A, B = variance_parts(M, T, cur, idx, idx)
        Mb = copy.deepcopy(M)
        Mb.refit(SIGMA, b)
        lam, E = cur.lam, cur.E
        r2, _, v, _ = whitened(Mb, T[:3, :3], T[:3, 3], m.N, m.c, lam, E, cur.variances(idx), idx)
        np.testing.assert_allclose(r, r2)
        np.testing.assert_allclose(A + b**2 * B, v, rtol=1e-9)


def test_deskew_variances_follow_the_points_moved_by_a_twist_error() -> None:
    """The residuals' change when the points are deskewed with a wrong twist, sampled,
    against :func:`deskew_variances` of the plane's Jacobian times the twist's covariance."""
    rng = np.random.default_rng(8)
    n = np.array([0.2, -0.9, 0.1])
    n /= np.linalg.norm(n)
    a = np.cross(n, [0.0, 0.0, 1.0])
    a /= np.linalg.norm(a)
    uv = rng.uniform(-0.5, 0.5, (3000, 2)) * [6.0, 2.0]  # a long patch: its axes well defined
    P = -6.0 * n + uv[:, :1] * a + uv[:, 1:] * np.cross(n, a)
    P += 0.0002 * rng.standard_normal((len(P), 1)) * n  # (the fit moves with the noise too)
    t = rng.uniform(-0.5, 0.5, len(P))  # times over the span, as the extraction scales them
    fit = tls_fit(P)
    normal = fit[2][:, 2] * np.sign(fit[2][:, 2] @ n)
    J = deskew_jacobian(P, t, normal, fit)
    per_axis = np.r_[np.full(3, 1e-4**2), np.full(3, 1e-3**2)]  # small: first order
    cov = (J * per_axis) @ J.T
    m = Moments.of_points([P])
    lam, E = np.linalg.eigh(m.S)
    predicted = deskew_variances(m, lam, E, cov[None])[0]
    d = -normal @ m.c[0]
    r0, _, _ = moment_residuals(np.eye(3), np.zeros(3), normal[None], np.r_[d], m.N, m.c, lam, E)
    changes = []
    for _ in range(400):
        dw, dv = rng.normal(0, np.sqrt(per_axis[:3])), rng.normal(0, np.sqrt(per_axis[3:]))
        Q = P + t[:, None] * (np.cross(dw, P) + dv)
        mq = Moments.of_points([Q])
        lq, Eq = np.linalg.eigh(mq.S)
        Eq = Eq * np.sign(np.einsum("kij,kij->kj", Eq, E))[:, None, :]  # the same axes' signs
        rq, _, _ = moment_residuals(np.eye(3), np.zeros(3), normal[None], np.r_[d], mq.N,
                                    mq.c, lq, Eq)  # fmt: skip
        changes.append(rq[0] - r0[0])
    sampled = np.var(np.array(changes), axis=0)
    # offset and the two tilts (the thickness residual does not move to first order)
    np.testing.assert_allclose(sampled[[0, 2, 3]], predicted[[0, 2, 3]], rtol=0.2)


def test_the_deskew_variance_switches_on_the_planes_jacobians() -> None:
    cfg = PlanodomConfig.from_dict({"planemap": {"deskew_variance": "twist_change"}})
    assert cfg.extraction.deskew_jacobian
    assert not PlanodomConfig().extraction.deskew_jacobian
