"""Each epoch's deskewing error sized by its planes (planodom.smoothing.deskew_epoch) against
the exact information of a coplanar twist fit on simulated planes, a Monte Carlo of the
fused estimate, and where the batch's covariances take it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from planodom.config import PlanodomConfig, SmoothingConfig
from planodom.errors import ConfigError
from planodom.extraction.planes.fit import deskew_jacobian, tls_covariance, tls_fit
from planodom.geometry import Plane
from planodom.odometry.relative import RelativePose
from planodom.se3 import se3_exp
from planodom.smoothing.batch_covariances import sandwich_inputs
from planodom.smoothing.deskew_epoch import (
    COPLANAR_RATIO,
    epoch_sizes,
    fused,
    plane_information,
)
from planodom.smoothing.deskew_scale import scaled_motion_change
from planodom.smoothing.sandwich import deskew_motion_change

SIGMA = 0.01  # m, the points' noise along the normal
NORMALS = np.array(
    [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.6, -0.8, 0.0], [0.7, 0.7, 0.14]]
)
OFFSETS = np.array([1.8, -6.0, -4.0, -9.0, -12.0])  # n . p + d = 0, normals towards the sensor


def _patch(n: np.ndarray, d: float, rng: np.random.Generator, k: int) -> np.ndarray:
    """(k, 3) points spread over 12 m x 12 m of the plane ``n . p + d = 0``, exact."""
    B = np.linalg.svd(n[None])[2][1:]  # (2, 3) tangent basis
    return -d * n + rng.uniform(-6.0, 6.0, (k, 2)) @ B


def _planes(times: str, seed: int = 0, k: int = 3000) -> tuple[list[Plane], np.ndarray]:
    """The five planes' fits (covariance, deskew Jacobian) from noisy points with times
    (units of the span) uniform in [0, 1] ("uniform", independent of where the point lies)
    or rising along the plane ("along": a sweep), and the exact information (6, 6) a fit of
    the twist error by the points' coplanarity gets (per (rad, m)^2 per span): the Schur
    complement of the planes' own parameters in the linear model ``n.p + d + t g.e``."""
    rng = np.random.default_rng(seed)
    planes, info = [], np.zeros((6, 6))
    for n, d in zip(NORMALS / np.linalg.norm(NORMALS, axis=1)[:, None], OFFSETS, strict=True):
        p = _patch(n, d, rng, k)
        if times == "uniform":
            t = rng.uniform(0.0, 1.0, k)
        else:
            u = p @ np.linalg.svd(n[None])[2][1]
            t = (u - u.min()) / np.ptp(u) + rng.uniform(-0.05, 0.05, k)
        noisy = p + rng.normal(0.0, SIGMA, k)[:, None] * n
        c, evals, evecs = tls_fit(noisy)
        normal = evecs[:, 2] if evecs[:, 2] @ n > 0 else -evecs[:, 2]
        cov = tls_covariance(evals[None], evecs[None], c[None], np.array([k]), 1e-6)[0]
        J = deskew_jacobian(noisy, t, normal)
        planes.append(Plane(normal, float(-normal @ c), cov, deskew_jacobian=J))
        # the oracle: rows t_i (p_i x n, n) for e, (p_i . B, 1) for the plane's (dn, dd)
        G = t[:, None] * np.hstack([np.cross(p, n), np.tile(n, (k, 1))])
        H = np.hstack([p @ np.linalg.svd(n[None])[2][1:].T, np.ones((k, 1))])
        HG = np.linalg.lstsq(H, G, rcond=None)[0]
        info += (G.T @ G - G.T @ H @ HG) / SIGMA**2
    return planes, info


def _whitened_eigenvalues(S: np.ndarray, M: np.ndarray) -> np.ndarray:
    L = np.linalg.cholesky(M)
    Li = np.linalg.inv(L)
    return np.linalg.eigvalsh(Li @ S @ Li.T)


def test_coplanarity_holds_a_third_of_the_planes_information() -> None:
    planes, exact = _planes("uniform")
    model = plane_information(planes) / COPLANAR_RATIO
    eig = _whitened_eigenvalues(exact, model)
    assert 0.85 < eig.min() and eig.max() < 1.15, eig  # ratio 1 would give ~1/3
    # Points seen in a sweep along the plane: their time is a function of where they lie,
    # and a twist error's displacement that is affine along the plane is taken by the
    # plane's own tilt: the coplanarity sees next to nothing along three directions that
    # the model credits (a limit of the model, docs/RESULTS.md NEESRUN).
    planes, exact = _planes("along", seed=1)
    eig = _whitened_eigenvalues(exact, plane_information(planes) / COPLANAR_RATIO)
    assert np.sum(eig < 0.05) == 3, eig


def test_fused_is_the_error_of_the_estimate_with_its_prior() -> None:
    rng = np.random.default_rng(5)
    L = rng.normal(0.0, 1.0, (6, 6))
    P = L @ L.T
    P[2, :] = P[:, 2] = 0.0  # one axis known exactly: stays exact
    A = rng.normal(0.0, 1.0, (4, 6))  # rank 4 < 6: the prior alone along two directions
    info = A.T @ A
    n = 40000
    x = rng.multivariate_normal(np.zeros(6), P, n)
    y = x @ A.T + rng.normal(0.0, 1.0, (n, 4))
    # the estimate: the prior's mean plus its gain on the measurement
    gain = P @ A.T @ np.linalg.inv(A @ P @ A.T + np.eye(4))
    err = y @ gain.T - x
    got = fused(P, info)
    want = np.cov(err.T)
    scale = np.sqrt(np.outer(np.diag(want), np.diag(want))) + 1e-300
    ok = np.diag(P) > 0  # (the draws hold round-off along the exact axis)
    np.testing.assert_allclose((got / scale)[np.ix_(ok, ok)], (want / scale)[np.ix_(ok, ok)],
                               atol=0.03)  # fmt: skip
    assert np.abs(got[2]).max() < 1e-12 * np.abs(got).max()  # (round-off)
    np.testing.assert_allclose(fused(P, np.zeros((6, 6))), P, atol=1e-12)


def _first_step(cov: np.ndarray) -> RelativePose:
    w = np.array([0.01, -0.02, 0.05, 1.5, 0.2, 0.05])
    return RelativePose(
        se3_exp(w * 0.1), cov, prev=0, curr=1, time_spread=True, deskew_twist=w,
        deskew_times=(0.0, 0.07), interval_s=0.1, z_observed=True, sigma_z=1e-3,
    )  # fmt: skip


def test_epoch_sizes_per_epoch() -> None:
    planes, _ = _planes("uniform", k=500)
    prior = np.stack([np.diag([1e-6, 1e-6, 2e-6, 1e-4, 1e-4, 1e-5])] * 4)
    prior[3] = 0.0  # taken at one instant
    step = _first_step(np.diag([4e-6, 4e-6, 4e-6, 4e-4, 4e-4]))
    factors = {i: (0 if i < 2 else 1, p) for i, p in enumerate(planes)}
    factors[9] = factors[0]  # the same plane in a second factor counts once
    Q = epoch_sizes(prior, factors, [step])
    info0 = plane_information(planes[:2]) / COPLANAR_RATIO
    info1 = plane_information(planes[2:]) / COPLANAR_RATIO
    for info in (info0, info1):  # the rotation's only
        info[3:, :] = info[:, 3:] = 0.0
    # the first epoch: its first step's error over its span as the prior
    first = np.diag(np.append([4e-6, 4e-6, 4e-6, 4e-4, 4e-4], 1e-6)) * 0.7**2
    np.testing.assert_allclose(Q[0], fused(first, info0), rtol=1e-9, atol=1e-20)
    np.testing.assert_allclose(Q[1], fused(prior[1], info1), rtol=1e-9, atol=1e-20)
    np.testing.assert_allclose(Q[2], prior[2])  # no planes: the prior
    assert not np.any(Q[3])
    assert np.all(np.diag(Q[1])[:3] < np.diag(prior[1])[:3])
    np.testing.assert_allclose(Q[1][3:, 3:], prior[1][3:, 3:])  # (a diagonal prior)
    # without a usable first step the first epoch's prior is the run's
    Q = epoch_sizes(prior, factors, [replace(step, covariance=None)])
    np.testing.assert_allclose(Q[0], fused(prior[0], info0), rtol=1e-9, atol=1e-20)


def test_sandwich_inputs_with_epoch() -> None:
    planes, _ = _planes("uniform", k=500)
    w = np.array([0.0, 0.0, 0.1, 2.0, 0.0, 0.0])
    rels = []
    for k in range(1, 6):
        wk = w + np.array([0.0, 0.01 * k**2, 0.02 * k, 0.1 * k, 0.0, 0.0])
        rels.append(
            RelativePose(
                se3_exp(wk * 0.1),
                np.eye(5) * 1e-6,
                prev=k - 1,
                curr=k,
                time_spread=True,
                deskew_twist=w + 0.9 * (wk - w),
                deskew_times=(0.0, 0.09),
                interval_s=0.1,
                z_observed=True,
                sigma_z=1e-3,
            )  # fmt: skip
        )
    factors = {i: (i % 6, p) for i, p in enumerate(planes)}
    cfg = SmoothingConfig(covariance_model="sandwich")
    run, _ = sandwich_inputs(cfg, factors, rels, 6)
    epoch, _ = sandwich_inputs(cfg.model_copy(update={"sandwich_motion_scale": "epoch"}),
                               factors, rels, 6)  # fmt: skip
    want = scaled_motion_change(deskew_motion_change(rels, 6), rels)[0]
    assert run is not None and epoch is not None
    np.testing.assert_allclose(run, want)
    np.testing.assert_allclose(epoch, epoch_sizes(want, factors, rels))


def test_option_value_epoch() -> None:
    assert SmoothingConfig().sandwich_motion_scale == "run"
    cfg = PlanodomConfig().updated({"smoothing.sandwich_motion_scale": "epoch"})
    assert cfg.smoothing.sandwich_motion_scale == "epoch"
    with pytest.raises(ConfigError, match="sandwich_motion_scale"):
        PlanodomConfig().updated({"smoothing.sandwich_motion_scale": "epochs"})
