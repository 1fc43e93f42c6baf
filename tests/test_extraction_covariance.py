"""The TLS plane covariance against a Monte Carlo estimate, and the CPEF weight."""

from __future__ import annotations

import numpy as np

from planodom.extraction.confidence import cpef
from planodom.extraction.fitting import PlaneFit, robust_plane_fit, tls_covariance, tls_fit


def _patch(n_pts: int, rng) -> tuple[np.ndarray, np.ndarray, float]:
    """Points on a tilted 4 m x 1.5 m patch 6 m from the origin, its normal and offset."""
    n = np.array([0.6, -0.48, 0.64])
    n /= np.linalg.norm(n)
    e1 = np.cross(n, [0, 0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    c = 6.0 * n + np.array([1.0, 2.0, 0.5]) - (np.array([1.0, 2.0, 0.5]) @ n) * n
    uv = rng.uniform([-2, -0.75], [2, 0.75], (n_pts, 2))
    return c + uv[:, :1] * e1 + uv[:, 1:] * e2, n, float(-n @ c)


def test_covariance_matches_monte_carlo():
    rng = np.random.default_rng(7)
    sigma, n_pts, trials = 0.02, 40, 4000
    pts, n_true, _ = _patch(n_pts, rng)
    noisy = pts[None] + sigma * rng.standard_normal((trials, n_pts, 3))
    c = noisy.mean(axis=1)
    q = noisy - c[:, None]
    vals, vecs = np.linalg.eigh(np.einsum("tni,tnj->tij", q, q))
    normals = vecs[:, :, 0] * np.sign(vecs[:, :, 0] @ n_true)[:, None]
    offsets = -np.einsum("ti,ti->t", normals, c)
    sample = np.cov(np.column_stack([normals, offsets]).T)
    # Predicted from each trial's own fit (sigma estimated from its residuals), averaged.
    pred = np.zeros((4, 4))
    for k in range(0, trials, 20):
        cc, ev, V = tls_fit(noisy[k])
        fit = PlaneFit(np.arange(n_pts), V[:, 2], float(-V[:, 2] @ cc), cc, ev, V)
        pred += tls_covariance(fit, 0.0)
    pred /= len(range(0, trials, 20))
    assert np.linalg.norm(pred - sample) / np.linalg.norm(sample) < 0.1
    np.testing.assert_allclose(np.diag(pred), np.diag(sample), rtol=0.12)
    # Rank 3: nothing along the normal.
    assert abs(n_true @ pred[:3, :3] @ n_true) < 1e-3 * np.trace(pred[:3, :3])


def test_covariance_is_floored_for_exact_data():
    rng = np.random.default_rng(1)
    pts, _, _ = _patch(30, rng)
    fit = robust_plane_fit(pts, 3.5)
    cov = tls_covariance(fit, 1e-4)
    assert np.all(np.isfinite(cov)) and np.linalg.matrix_rank(cov, tol=1e-20) == 3


def test_cpef_factors():
    rng = np.random.default_rng(2)
    pts, n, _ = _patch(200, rng)
    view = np.zeros(3)
    base = dict(normal=n, points=pts, viewpoint=view, points_ref=50.0, width_ref_m=1.0)
    w = cpef(0.006, 0.006, 200, 1.0, **base)
    assert 0 < w <= 1
    assert cpef(0.03, 0.006, 200, 1.0, **base) < w  # larger residual
    assert cpef(0.006, 0.006, 20, 1.0, **base) < w  # fewer points
    assert cpef(0.006, 0.006, 200, 0.1, **base) < w  # thinner
    grazing = dict(base, viewpoint=pts.mean(axis=0) + 50 * np.cross(n, [0, 0, 1.0]))
    assert cpef(0.006, 0.006, 200, 1.0, **grazing) < w  # grazing incidence
