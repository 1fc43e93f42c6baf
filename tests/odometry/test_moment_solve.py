"""The moments' solve with its analytic Jacobian (planodom.odometry.moment_solve)."""

import numpy as np

from planodom.geometry import invert_transform, se3_exp, se3_log
from planodom.odometry.moment_solve import _cross, moment_jacobian, moment_solve
from planodom.oracle import SurfaceMoments, _residuals, _roots, relative_pose, surface_moments

#: Surfaces (unit normal, offset) in the previous frame: ground, three walls.
SURFACES = [
    (np.array([0.0, 0.0, 1.0]), 1.0),
    (np.array([1.0, 0.0, 0.0]), -6.0),
    (np.array([0.0, 1.0, 0.0]), -4.0),
    (np.array([np.cos(0.5), -np.sin(0.5), 0.0]), 3.0),
]


def _epochs(T_prev_curr: np.ndarray, noise: float) -> tuple[SurfaceMoments, SurfaceMoments]:
    """Both epochs' moments of 300 points per surface (curr = T^-1 prev), noisy."""
    rng = np.random.default_rng(5)
    T_curr_prev = invert_transform(T_prev_curr)
    pts, labels = [], []
    for i, (n, d) in enumerate(SURFACES):
        u = np.cross(n, [0.3, 0.5, 0.8])
        u /= np.linalg.norm(u)
        ab = rng.uniform(-1.5, 1.5, (300, 2))
        pts.append(-d * n + ab[:, :1] * u + ab[:, 1:] * np.cross(n, u))
        labels.append(np.full(300, i))
    p, lab = np.concatenate(pts), np.concatenate(labels)
    q = p @ T_curr_prev[:3, :3].T + T_curr_prev[:3, 3]
    prev = surface_moments(p + noise * rng.standard_normal(p.shape), lab)
    curr = surface_moments(q + noise * rng.standard_normal(q.shape), lab)
    return prev, curr


TRUTH = se3_exp(np.array([0.002, -0.001, 0.03, 0.8, 0.05, 0.01]))
START = TRUTH @ se3_exp(np.array([0.004, 0.003, -0.01, 0.03, -0.04, 0.02]))


def test_the_jacobian_is_the_residuals_derivative():
    prev, curr = _epochs(TRUTH, 0.01)
    roots = (_roots(prev.scatter), _roots(curr.scatter))
    J = moment_jacobian(START, prev, curr, roots)
    h = 1e-6  # central differences, independent of the closed form
    for i, e in enumerate(np.eye(6)):
        plus = _residuals(START @ se3_exp(h * e), prev, curr, roots)
        minus = _residuals(START @ se3_exp(-h * e), prev, curr, roots)
        np.testing.assert_allclose(J[:, i], (plus - minus) / (2 * h), atol=1e-6)


def test_noise_free_planes_give_the_truth():
    prev, curr = _epochs(TRUTH, 0.0)
    est = moment_solve(prev, curr, START)
    assert est.status == "ok" and est.measured.all()
    assert np.abs(se3_log(invert_transform(TRUTH) @ est.T_prev_curr)).max() < 1e-9


def test_noisy_planes_give_the_oracles_solution():
    prev, curr = _epochs(TRUTH, 0.02)
    est = moment_solve(prev, curr, START)
    ref = relative_pose(prev, curr, START)  # forward differences, same cost
    assert est.status == ref.status == "ok"
    assert np.abs(se3_log(invert_transform(ref.T_prev_curr) @ est.T_prev_curr)).max() < 1e-7


def test_the_cross_product_is_numpys_to_the_bit():
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(7, 3)) * 1e3, rng.normal(size=(7, 3)) * 1e-3
    assert np.array_equal(_cross(a, b), np.cross(a, b))
    assert np.array_equal(_cross(a[:0], b[:0]), np.cross(a[:0], b[:0]).reshape(0, 3))
