"""Both epochs' deskewing errors in the steps' stated covariances
(planodom.odometry.stated_deskew, ``odometry.stated_deskew_noise``): the stated term against
a Monte-Carlo of steps refitted (scipy, nonlinear) to planes moved by drawn twist errors,
the run-wide twist change against hand-computed differences, and the odometry's estimate
unchanged by the option."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import sqrtm
from scipy.optimize import least_squares

from planodom.config import PlanodomConfig
from planodom.experiments.generalisation import declared_sweep, world_for
from planodom.geometry import Plane, rpy_from_rotation, transform_planes
from planodom.odometry import run_odometry
from planodom.odometry.plane_deskew import twist_covariance
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.stated_deskew import (
    epoch_deskew_covariances,
    run_twist_change,
    shared_term,
    stated_relatives,
    with_stated_deskew,
)
from planodom.se3 import se3_exp
from planodom.simulation.random_world import simulate_world, world_fields

SPAN_A, SPAN_B = 0.1, 0.15  # s, the two epochs' spans
SIGMA = twist_covariance((0.003, 0.04))  # rad/s, m/s: the twist errors drawn


def _cov(rng: np.random.Generator, n: np.ndarray) -> np.ndarray:
    """A random rank-3 (4, 4) covariance of ``(n, d)``: no variance along ``n`` itself."""
    P = np.eye(4)
    P[:3, :3] -= np.outer(n, n)
    A = rng.normal(size=(4, 4)) * [1e-3, 1e-3, 1e-3, 1e-2]
    return P @ (A @ A.T + 1e-6 * np.eye(4)) @ P


def _jacobian(rng: np.random.Generator, n: np.ndarray) -> np.ndarray:
    """A random (4, 6) deskewing Jacobian that keeps the normal unit."""
    P = np.eye(4)
    P[:3, :3] -= np.outer(n, n)
    return P @ rng.normal(size=(4, 6))


def _epochs(rng: np.random.Generator, T_a_b: np.ndarray) -> tuple[list[Plane], list[Plane]]:
    """Six planes of epoch a and the same seen from b (exactly ``T_a_b``)."""
    normals = rng.normal(size=(6, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    offsets = rng.uniform(-8.0, 8.0, 6)
    a = [Plane(n, float(d), _cov(rng, n), deskew_jacobian=_jacobian(rng, n))
         for n, d in zip(normals, offsets, strict=True)]  # fmt: skip
    n_b, d_b = transform_planes(np.linalg.inv(T_a_b), normals, offsets)
    b = [Plane(n, float(d), _cov(rng, n), deskew_jacobian=_jacobian(rng, n))
         for n, d in zip(n_b, d_b, strict=True)]  # fmt: skip
    return a, b


def _refit_steps(T: np.ndarray, a: list[Plane], b: list[Plane], shifts: np.ndarray) -> np.ndarray:
    """(N, 5) (roll, pitch, yaw, x, y) of the step refitted (nonlinear weighted least
    squares over the plane pairs, both planes' covariances) to a's planes moved by
    ``shifts[i, 0]`` and b's by ``shifts[i, 1]`` (N, 2, 6) through their Jacobians, less
    those of ``T``."""
    roots = []
    for pa, pb in zip(a, b, strict=True):
        J = np.eye(4)
        J[:3, :3], J[3, :3] = T[:3, :3], -(T[:3, 3] @ T[:3, :3])
        W = np.linalg.pinv(pa.covariance + J @ pb.covariance @ J.T, rcond=1e-9, hermitian=True)
        roots.append(np.real(sqrtm(W)))

    def moved(planes: list[Plane], shift: np.ndarray) -> list[np.ndarray]:
        out = [p.coefficients + p.deskew_jacobian @ shift for p in planes]
        return [c / np.linalg.norm(c[:3]) for c in out]

    base = np.r_[rpy_from_rotation(T[:3, :3]), T[:2, 3]]
    out = []
    for shift_a, shift_b in shifts:
        ca, cb = moved(a, shift_a), moved(b, shift_b)

        def residual(xi: np.ndarray, ca=ca, cb=cb) -> np.ndarray:  # noqa: ANN001
            Tx = T @ se3_exp(xi)
            r = []
            for x, y, L in zip(ca, cb, roots, strict=True):
                n, d = transform_planes(Tx, y[None, :3], np.array([y[3]]))
                r.append(L @ (x - np.append(n[0], d[0])))
            return np.concatenate(r)

        xi = least_squares(residual, np.zeros(6), xtol=1e-14, ftol=1e-14, gtol=1e-14).x
        Tx = T @ se3_exp(xi)
        out.append(np.r_[rpy_from_rotation(Tx[:3, :3]), Tx[:2, 3]] - base)
    return np.array(out)


def _step() -> tuple[RelativePose, list[Plane], list[Plane], np.ndarray]:
    rng = np.random.default_rng(11)
    T = se3_exp(np.array([0.03, -0.02, 0.3, 1.2, 0.2, 0.05]))
    a, b = _epochs(rng, T)
    pairs = np.column_stack([np.arange(6), np.arange(6)])
    rel = RelativePose(T, np.eye(5) * 1e-8, Status.OK, pairs, prev=0, curr=1)
    return rel, a, b, T


def test_the_stated_term_is_the_covariance_of_steps_refitted_under_drawn_twist_errors():
    """The oracle: each epoch's twist error drawn from N(0, SIGMA) (independent epochs),
    its planes moved by span x Jacobian x error, the step refitted (nonlinear); the sample
    covariance of (roll, pitch, yaw, x, y) over 600 draws is the term within sampling
    error (variances about 6 %, 20 % allowed on the diagonal). Then exactly, without
    sampling: the refits at the 24 sigma points of the two errors (+- sqrt(12) times each
    column of their covariance's root) give the term within 2 % of its scale. Both fail
    with either end left out."""
    rel, a, b, T = _step()
    Qa, Qb = SPAN_A**2 * SIGMA, SPAN_B**2 * SIGMA
    term = shared_term(rel, a, b, Qa, Qb)
    one_ends = (shared_term(rel, a, b, Qa, 0 * Qb), shared_term(rel, a, b, 0 * Qa, Qb))
    rng = np.random.default_rng(5)
    draws = rng.multivariate_normal(np.zeros(6), SIGMA, size=(600, 2))
    shifts = draws * np.array([SPAN_A, SPAN_B])[None, :, None]
    sample = np.cov(_refit_steps(T, a, b, shifts).T)
    assert np.all(np.abs(np.diag(sample) / np.diag(term) - 1.0) <= 0.2)
    for one_end in one_ends:
        assert np.any(np.abs(np.diag(sample) / np.diag(one_end) - 1.0) > 0.2)
    root = np.linalg.cholesky(np.kron(np.diag([SPAN_A**2, SPAN_B**2]), SIGMA))
    points = np.sqrt(12.0) * np.concatenate([root.T, -root.T]).reshape(24, 2, 6)
    steps = _refit_steps(T, a, b, points)
    exact = steps.T @ steps / 24.0  # the points' mean is zero by symmetry
    scale = np.sqrt(np.outer(np.diag(term), np.diag(term)))
    assert np.all(np.abs(exact - term) <= 0.02 * scale)
    for one_end in one_ends:
        assert np.any(np.abs(exact - one_end) > 0.02 * scale)


def test_epochs_span_and_no_twist():
    r = RelativePose(np.eye(4), np.eye(5), prev=0, curr=1, deskew_twist=np.ones(6),
                     deskew_times=(-0.02, 0.08))  # fmt: skip
    untwisted = RelativePose(np.eye(4), np.eye(5), prev=1, curr=2, deskew_times=(0.0, 0.1))
    Q = epoch_deskew_covariances([None, r, untwisted], SIGMA)
    np.testing.assert_allclose(Q[1], 0.08**2 * SIGMA)
    assert not np.any(Q[0]) and not np.any(Q[2])


def test_run_twist_change_against_hand_computed_differences():
    """Three successive OK steps at 0.1 s with yaw rates 1, 2, 4 rad/s and speeds 5, 5, 6
    m/s: differences (1, 0) and (2, 1): rms rate sqrt(5 / 2), speed sqrt(1 / 2)."""
    times = np.array([0.0, 0.1, 0.2, 0.3])
    results: list[RelativePose | None] = [None]
    for k, (w, v) in enumerate(((1.0, 5.0), (2.0, 5.0), (4.0, 6.0)), start=1):
        T = se3_exp(np.array([0, 0, w * 0.1, v * 0.1, 0, 0]))
        results.append(RelativePose(T, np.eye(5), Status.OK, prev=k - 1, curr=k))
    expected = twist_covariance((np.sqrt(2.5), np.sqrt(0.5)))
    np.testing.assert_allclose(run_twist_change(results, times), expected, rtol=1e-9)
    results[2] = RelativePose(results[2].T_prev_curr, None, Status.DEGENERATE, prev=1, curr=2)
    assert not np.any(run_twist_change(results, times))  # no two successive OK steps


def test_unresolved_superseded_and_unknown_covariances_are_left():
    rel, a, b, _ = _step()
    Q = np.stack([SPAN_A**2 * SIGMA, SPAN_B**2 * SIGMA])
    unresolved = RelativePose(rel.T_prev_curr, rel.covariance, Status.UNRESOLVED,
                              rel.associations, prev=0, curr=1)  # fmt: skip
    unknown = RelativePose(rel.T_prev_curr, None, Status.OK, rel.associations, prev=0, curr=1)
    out = stated_relatives([rel, unresolved, unknown], [a, b], Q)
    assert out[1] is unresolved and out[2] is unknown
    np.testing.assert_allclose(out[0].covariance, rel.covariance + shared_term(rel, a, b, *Q))
    assert stated_relatives([rel], [a, b], Q, superseded=[1])[0] is rel


@pytest.fixture(scope="module")
def runs():
    """A short simulated 2D-rig run (procedural world 144, 6 mm, 10 epochs, all OK) with the
    default config and with the option."""
    world = world_for(144)
    sim = simulate_world(world, 0.006, n_epochs=10, all_fields=True)
    scans = world_fields(world, sim)
    base = PlanodomConfig().updated({"extraction.deskew_jacobian": True})
    default = run_odometry(scans, declared_sweep(world, base))
    option = base.updated({"odometry.stated_deskew_noise": "shared"})
    return default, run_odometry(scans, declared_sweep(world, option))


def test_the_option_leaves_the_estimate_and_only_grows_the_stated_covariances(runs):
    default, option = runs
    assert np.array_equal(default.poses, option.poses)
    grown = 0
    for r0, r1 in zip(default.results[1:], option.results[1:], strict=True):
        assert np.array_equal(r0.T_prev_curr, r1.T_prev_curr) and r0.status == r1.status
        if r0.covariance is None:
            continue
        extra = np.asarray(r1.covariance) - np.asarray(r0.covariance)
        assert np.linalg.eigvalsh(0.5 * (extra + extra.T)).min() >= -1e-12 * np.abs(extra).max()
        grown += bool(np.any(extra))
    assert grown >= 8
    restated = with_stated_deskew(default)  # the post-pass on the default's run is the option
    for r0, r1 in zip(restated.results[1:], option.results[1:], strict=True):
        np.testing.assert_array_equal(r0.covariance, r1.covariance)
