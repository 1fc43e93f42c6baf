"""The twist from coplanarity: ground truth on synthetic rooms and streets, consistency."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.extraction.twist_fit import fit_twist, normal_equations
from planodom.geometry import invert_transform, se3_exp

XI = np.array([0.05, -0.04, 0.6, 3.0, 0.4, 0.1])  # rad/s, m/s: a brisk turn
EPOCH_S = 0.1


def box_room(rng: np.random.Generator, per_plane: int = 300) -> list[np.ndarray]:
    """Points (at the reference time) on the walls, floor and ceiling of a 12 x 8 x 3 m
    room around the origin, with their plane (n, d), and not parallel to any axis (a
    yawed room)."""
    yaw = 0.3
    R = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1.0]])
    half = np.array([6.0, 4.0, 1.5])
    centre = np.array([0.5, -0.3, 0.4])
    pts = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            u = rng.uniform(-1, 1, (per_plane, 3)) * half
            u[:, axis] = sign * half[axis]
            pts.append(u @ R.T + centre)
    return pts


def street(rng: np.random.Generator, per_plane: int = 300) -> list[np.ndarray]:
    """Points on two facades (y = +-5 m) and the ground (z = -1.8 m), 40 m along x."""
    out = []
    for y in (-5.0, 5.0):
        p = np.column_stack(
            [
                rng.uniform(-20, 20, per_plane),
                np.full(per_plane, y),
                rng.uniform(-1.8, 6, per_plane),
            ]
        )
        out.append(p)
    g = np.column_stack(
        [rng.uniform(-20, 20, per_plane), rng.uniform(-5, 5, per_plane), np.full(per_plane, -1.8)]
    )
    out.append(g)
    return out


def seen(planes: list[np.ndarray], xi: np.ndarray, rng: np.random.Generator, noise: float = 0.0):
    """Raw points (each in the base frame of its own time), times and inliers: the points
    ``p_ref`` of each plane seen at random times in [0, EPOCH_S] (several sweeps over each
    wall: times independent of the position), ``p_t = exp(t xi)^-1 p_ref`` by the
    batched closed form, plus isotropic noise."""
    ref = np.vstack(planes)
    t = rng.uniform(0.0, EPOCH_S, len(ref))
    T_t_ref = invert_transform(se3_exp(t[:, None] * xi))
    raw = np.einsum("nij,nj->ni", T_t_ref[:, :3, :3], ref) + T_t_ref[:, :3, 3]
    raw = raw + noise * rng.standard_normal(raw.shape)
    bounds = np.cumsum([0] + [len(p) for p in planes])
    inliers = [np.arange(a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    return raw, t, inliers


def test_recovers_true_twist_from_wrong_prior_box_room():
    rng = np.random.default_rng(0)
    planes = box_room(rng)
    raw, t, inl = seen(planes, XI, rng)
    prior = XI + np.array([0.1, -0.05, -0.3, -1.0, 0.5, 0.2])
    fit = fit_twist(raw, t, inl, prior, np.eye(6) * 1e-6, 1e-4, max_iterations=10)
    np.testing.assert_allclose(fit.twist, XI, atol=1e-9)
    assert fit.converged and fit.rank == 6 and fit.rms_m < 1e-9


def test_street_keeps_the_prior_along_it():
    # A street along x: a velocity along it moves no point off its plane (the twist's
    # rotation about x commutes with it): the prior's vx stays, the rest is recovered.
    rng = np.random.default_rng(1)
    truth = np.array([0.08, 0.0, 0.0, 8.0, 0.3, -0.1])
    raw, t, inl = seen(street(rng), truth, rng)
    prior = np.array([0.0, 0.0, 0.0, 6.5, 0.0, 0.0])
    P = np.diag([1.0, 1.0, 1.0, 0.1, 0.1, 0.1])
    fit = fit_twist(raw, t, inl, prior, P, 1e-4, max_iterations=10)
    expected = truth.copy()
    expected[3] = prior[3]
    np.testing.assert_allclose(fit.twist, expected, atol=1e-8)
    assert fit.rank == 5
    assert abs(fit.data_information[3, 3]) < 1e-6 * np.trace(fit.data_information)


def test_gradient_matches_finite_differences_of_the_coplanarity_cost():
    # b is half the gradient of F(xi) = sum over planes of the smallest scatter eigenvalue
    # of the deskewed inliers (their TLS residual): an independent computation by eigvalsh.
    from planodom.extraction.deskew import deskew_points

    rng = np.random.default_rng(2)
    planes = box_room(rng, 80)
    raw, t, inl = seen(planes, XI, rng, noise=0.01)
    xi0 = XI + np.array([0.02, 0.01, -0.05, 0.3, -0.2, 0.1])

    def cost(xi):
        p = deskew_points(raw, t, xi)
        total = 0.0
        for i in inl:
            q = p[i] - p[i].mean(axis=0)
            total += np.linalg.eigvalsh(q.T @ q)[0]
        return total

    bounds = np.cumsum([0] + [len(i) for i in inl])
    _, b, _ = normal_equations(deskew_points(raw, t, xi0), t, bounds, xi0)
    h = 1e-6
    grad = np.array([(cost(xi0 + h * e) - cost(xi0 - h * e)) / (2 * h) for e in np.eye(6)])
    np.testing.assert_allclose(2 * b, grad, rtol=1e-4, atol=1e-9)


def test_covariance_is_consistent_monte_carlo():
    # NEES of the estimate against the truth with the returned information: chi-square 6
    # when the prior is drawn from its own covariance (200 trials: mean 6 +- 0.25).
    rng = np.random.default_rng(4)
    sigma = 0.01
    P = np.diag([1.0 / 0.05**2] * 3 + [1.0 / 0.5**2] * 3)
    L = np.linalg.cholesky(np.linalg.inv(P))
    nees = []
    for _ in range(200):
        planes = box_room(rng, 60)
        raw, t, inl = seen(planes, XI, rng, noise=sigma)
        prior = XI + L @ rng.standard_normal(6)
        fit = fit_twist(raw, t, inl, prior, P, sigma)
        e = fit.twist - XI
        nees.append(float(e @ fit.information @ e))
    assert np.mean(nees) == pytest.approx(6.0, abs=0.8)


def test_no_planes_gives_the_prior():
    P = np.eye(6)
    fit = fit_twist(np.zeros((2, 3)), np.zeros(2), [np.array([0, 1])], XI, P, 0.01)
    np.testing.assert_array_equal(fit.twist, XI)
    np.testing.assert_array_equal(fit.information, P)
    assert fit.rank == 0 and fit.iterations == 0


def test_information_matches_the_cost_curvature_at_the_truth():
    # At sigma = 0 and the true twist the residuals vanish, so Gauss-Newton's H is the
    # exact half Hessian of F (previous test): second differences of F agree.
    from planodom.extraction.deskew import deskew_points

    rng = np.random.default_rng(5)
    planes = box_room(rng, 80)
    raw, t, inl = seen(planes, XI, rng)
    bounds = np.cumsum([0] + [len(i) for i in inl])
    H, _, _ = normal_equations(deskew_points(raw, t, XI), t, bounds, XI)

    def cost(xi):
        p = deskew_points(raw, t, xi)
        return sum(
            np.linalg.eigvalsh((p[i] - p[i].mean(0)).T @ (p[i] - p[i].mean(0)))[0] for i in inl
        )

    h = 1e-4
    E = np.eye(6) * h
    num = np.array(
        [
            [
                (
                    cost(XI + E[i] + E[j])
                    - cost(XI + E[i] - E[j])
                    - cost(XI - E[i] + E[j])
                    + cost(XI - E[i] - E[j])
                )
                / (4 * h * h)
                for j in range(6)
            ]
            for i in range(6)
        ]
    )
    np.testing.assert_allclose(2 * H, num, rtol=2e-3, atol=1e-3 * np.abs(H).max())


def test_warm_start_and_sigma_stop_reach_the_truth_in_fewer_steps():
    # Started from a twist near the answer, the fit ends at the truth (sigma = 0) and
    # stops once its step is under a tenth of a sigma; the prior's value, not the start,
    # is what the prior pulls towards (no prior information here).
    rng = np.random.default_rng(6)
    raw, t, inl = seen(box_room(rng), XI, rng)
    prior = XI + np.array([0.1, -0.05, -0.3, -1.0, 0.5, 0.2])
    near = XI + 1e-4
    cold = fit_twist(raw, t, inl, prior, np.eye(6) * 1e-6, 1e-4, max_iterations=10)
    warm = fit_twist(
        raw, t, inl, prior, np.eye(6) * 1e-6, 1e-4, max_iterations=10, start=near,
        step_sigmas=0.1, evaluate_solution=False,
    )  # fmt: skip
    np.testing.assert_allclose(warm.twist, XI, atol=1e-9)
    assert warm.converged and warm.iterations < cold.iterations


def test_displacement_information_is_the_points_motion_along_their_normals():
    # d^T M d against an independent computation: the inliers deskewed with xi + d and
    # with xi, their difference along each true plane's normal, squared, summed, over
    # sigma^2 (first order: d small).
    from planodom.extraction.deskew import deskew_points

    rng = np.random.default_rng(7)
    planes = box_room(rng, 100)
    raw, t, inl = seen(planes, XI, rng)
    sigma = 0.01
    fit = fit_twist(raw, t, inl, XI, np.zeros((6, 6)), sigma, max_iterations=1)
    normals = []
    for p in planes:
        q = p - p.mean(axis=0)
        normals.append(np.linalg.eigh(q.T @ q)[1][:, 0])
    for d in (1e-5 * rng.standard_normal(6), 1e-5 * np.eye(6)[2], 1e-5 * np.eye(6)[3]):
        moved = deskew_points(raw, t, XI + d) - deskew_points(raw, t, XI)
        along = np.concatenate([moved[i] @ n for i, n in zip(inl, normals, strict=True)])
        expected = float(np.sum(along**2)) / sigma**2
        assert d @ fit.displacement_information @ d == pytest.approx(expected, rel=1e-3)
