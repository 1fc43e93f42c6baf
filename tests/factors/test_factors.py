"""Custom factors: analytic Jacobians vs central differences, 5-DoF semantics, plane factors."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planodom import geometry as g
from planodom_factors.planes import (
    anchor_pose,
    anchor_prior,
    anchored_plane_factor,
    orient_measurement,
    plane_factor,
    plane_noise,
    predict_plane,
)
from planodom_factors.pose5 import (
    _logmap,
    _logmap_derivative,
    pose5_error,
    pose5_factor,
    rotation_factor,
    vertical_factor,
)

X = gtsam.symbol_shorthand.X
L = gtsam.symbol_shorthand.L
A = gtsam.symbol_shorthand.A

UNIT5 = gtsam.noiseModel.Unit.Create(5)
UNIT3 = gtsam.noiseModel.Unit.Create(3)
UNIT1 = gtsam.noiseModel.Unit.Create(1)


def random_pose(rng: np.random.Generator, scale: float = 20.0) -> gtsam.Pose3:
    R = Rotation.random(random_state=rng).as_matrix()
    return gtsam.Pose3(g.make_transform(R, rng.uniform(-scale, scale, 3)))


def random_plane(rng: np.random.Generator) -> gtsam.OrientedPlane3:
    n = rng.normal(size=3)
    return gtsam.OrientedPlane3(np.append(n / np.linalg.norm(n), rng.uniform(-30, 30)))


def _retracted(values: gtsam.Values, key: int, delta: np.ndarray) -> gtsam.Values:
    out = gtsam.Values(values)
    if gtsam.Symbol(key).chr() == ord("l"):
        out.update(key, values.atOrientedPlane3(key).retract(delta))
    else:
        out.update(key, values.atPose3(key).retract(delta))
    return out


def numerical_jacobians(factor, values: gtsam.Values, h: float = 1e-6) -> list[np.ndarray]:
    """Central differences of ``unwhitenedError`` on each key's retraction."""
    jacobians = []
    for key in factor.keys():
        dim = 3 if gtsam.Symbol(key).chr() == ord("l") else 6
        cols = []
        for k in range(dim):
            e = np.zeros(dim)
            e[k] = h
            plus = factor.unwhitenedError(_retracted(values, key, e))
            minus = factor.unwhitenedError(_retracted(values, key, -e))
            cols.append((plus - minus) / (2 * h))
        jacobians.append(np.column_stack(cols))
    return jacobians


def analytic_jacobians(factor, values: gtsam.Values) -> list[np.ndarray]:
    """Jacobian blocks of the linearised factor (unit noise, so whitening is the identity)."""
    A_full, _ = factor.linearize(values).jacobian()
    blocks, col = [], 0
    for key in factor.keys():
        dim = 3 if gtsam.Symbol(key).chr() == ord("l") else 6
        blocks.append(A_full[:, col : col + dim])
        col += dim
    return blocks


def assert_jacobians_match(factor, values: gtsam.Values, atol: float = 1e-6) -> None:
    analytic, numerical = analytic_jacobians(factor, values), numerical_jacobians(factor, values)
    for Ha, Hn in zip(analytic, numerical, strict=True):
        np.testing.assert_allclose(Ha, Hn, atol=atol, rtol=1e-5)


@pytest.mark.parametrize("seed", range(8))
def test_pose5_jacobians_match_numerical(seed: int) -> None:
    rng = np.random.default_rng(seed)
    Ti, Tj = random_pose(rng), random_pose(rng)
    # A measurement near (not at) the prediction, so the error and Jr^-1 are non-trivial.
    measured = Ti.between(Tj).retract(rng.normal(scale=0.3, size=6))
    values = gtsam.Values()
    values.insert(X(0), Ti)
    values.insert(X(1), Tj)
    assert_jacobians_match(pose5_factor(X(0), X(1), measured, UNIT5), values)
    assert_jacobians_match(vertical_factor(X(0), X(1), 0.3, UNIT1), values)
    assert_jacobians_match(rotation_factor(X(0), X(1), measured, UNIT3), values)
    e5 = pose5_factor(X(0), X(1), measured, UNIT5).unwhitenedError(values)
    np.testing.assert_allclose(
        rotation_factor(X(0), X(1), measured, UNIT3).unwhitenedError(values), e5[:3]
    )


def test_pose5_error_components_and_free_z() -> None:
    rng = np.random.default_rng(1)
    Ti = random_pose(rng)
    T_ij = g.transform_from_rpy_xyz(0.01, -0.02, 0.3, 1.0, 0.5, 0.0)
    Tj = Ti.compose(gtsam.Pose3(T_ij))
    values = gtsam.Values()
    values.insert(X(0), Ti)
    values.insert(X(1), Tj)
    factor = pose5_factor(X(0), X(1), T_ij, UNIT5)
    np.testing.assert_allclose(factor.unwhitenedError(values), 0, atol=1e-12)
    # A vertical offset in frame i is invisible to the 5-DoF factor ...
    lifted = gtsam.Values()
    lifted.insert(X(0), Ti)
    lifted.insert(X(1), Ti.compose(gtsam.Pose3(g.make_transform(T_ij[:3, :3], [1.0, 0.5, 2.0]))))
    np.testing.assert_allclose(factor.unwhitenedError(lifted), 0, atol=1e-12)
    # ... and the vertical factor sees the change of world height.
    dz = lifted.atPose3(X(1)).translation()[2] - Ti.translation()[2]
    assert vertical_factor(X(0), X(1), 0.0, UNIT1).unwhitenedError(lifted)[0] == pytest.approx(dz)
    assert vertical_factor(X(0), X(1), dz, UNIT1).unwhitenedError(lifted)[0] == pytest.approx(0)
    # x, y and yaw errors land in their own components.
    moved = gtsam.Values()
    moved.insert(X(0), Ti)
    moved.insert(
        X(1), Ti.compose(gtsam.Pose3(g.transform_from_rpy_xyz(0.01, -0.02, 0.35, 1.2, 0.4)))
    )
    e = factor.unwhitenedError(moved)
    assert e[3] == pytest.approx(0.2) and e[4] == pytest.approx(-0.1)
    assert abs(e[2]) == pytest.approx(0.05, abs=2e-3)


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-5, 9e-4, 1.1e-3, 0.05, 0.7, 1.5, 2.0, 3.0, 3.14])
def test_compiled_logmap_and_its_derivative_match_gtsam(angle: float) -> None:
    """The compiled rotation-error kernel against gtsam's own Rot3.Logmap and
    LogmapDerivative (both sides of the Taylor thresholds; above 90 degrees the kernel
    defers to gtsam)."""
    rng = np.random.default_rng(int(angle * 1e4))
    for _ in range(20):
        axis = rng.normal(size=3)
        w = axis / np.linalg.norm(axis) * angle
        R = np.ascontiguousarray(gtsam.Rot3.Expmap(w).matrix())
        omega, ok = _logmap(R)
        assert ok == (angle < np.pi / 2)
        if ok:
            expected = gtsam.Rot3.Logmap(gtsam.Rot3(R))
            np.testing.assert_allclose(omega, expected, rtol=1e-14, atol=1e-300)
        np.testing.assert_allclose(
            _logmap_derivative(w), gtsam.Rot3.LogmapDerivative(w), rtol=0, atol=1e-15
        )


@pytest.mark.parametrize("scale", [1e-6, 1e-2, 0.5, 2.0])
def test_pose5_error_matches_the_numpy_gtsam_computation(scale: float) -> None:
    """pose5_error (compiled) against the same residual and Jacobians computed by numpy and
    gtsam's Rot3.Logmap / LogmapDerivative, at random poses and measurements (rotation
    errors up to ~3 rad at the largest scale: those beyond 90 degrees go to gtsam)."""
    rng = np.random.default_rng(int(scale * 1e6))
    for _ in range(50):
        Ti, rel = random_pose(rng), random_pose(rng, scale=3.0)
        Tj = Ti.compose(rel)
        measured = rel.retract(rng.normal(scale=scale, size=6)).matrix()
        Ti_m, Tj_m = Ti.matrix(), Tj.matrix()
        error, H_i, H_j = pose5_error(measured, Ti_m, Tj_m, jacobians=True)
        Ri_T = Ti_m[:3, :3].T
        R_pred = Ri_T @ Tj_m[:3, :3]
        t_pred = Ri_T @ (Tj_m[:3, 3] - Ti_m[:3, 3])
        e_rot = gtsam.Rot3.Logmap(gtsam.Rot3(measured[:3, :3].T @ R_pred))
        Jr_inv = gtsam.Rot3.LogmapDerivative(e_rot)
        skew = np.array(
            [[0, -t_pred[2], t_pred[1]], [t_pred[2], 0, -t_pred[0]], [-t_pred[1], t_pred[0], 0]]
        )
        np.testing.assert_allclose(error[:3], e_rot, rtol=0, atol=1e-13)
        np.testing.assert_allclose(error[3:], t_pred[:2] - measured[:2, 3], rtol=0, atol=1e-13)
        assert H_i is not None and H_j is not None
        np.testing.assert_allclose(H_i[:3, :3], -Jr_inv @ R_pred.T, rtol=0, atol=1e-13)
        np.testing.assert_allclose(H_j[:3, :3], Jr_inv, rtol=0, atol=1e-13)
        np.testing.assert_allclose(H_i[3:, :3], skew[:2], rtol=0, atol=1e-13)
        np.testing.assert_allclose(H_j[3:, 3:], R_pred[:2], rtol=0, atol=1e-13)
        np.testing.assert_array_equal(H_i[3:, 3:], [[-1, 0, 0], [0, -1, 0]])
        for H, zero in ((H_i, np.s_[:3, 3:]), (H_j, np.s_[:3, 3:]), (H_j, np.s_[3:, :3])):
            np.testing.assert_array_equal(H[zero], 0)


@pytest.mark.parametrize("seed", range(6))
def test_plane_factor_jacobians_match_numerical(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    pose, anchor = random_pose(rng), random_pose(rng)
    plane_a = random_plane(rng)
    plane_world = plane_a.transform(anchor.inverse())  # the same plane in the world frame
    measured = plane_world.transform(pose).retract(rng.normal(scale=0.05, size=3))
    values = gtsam.Values()
    values.insert(X(0), pose)
    values.insert(A(0), anchor)
    values.insert(L(0), plane_a)
    values.insert(L(1), plane_world)
    coeffs = np.asarray(measured.planeCoefficients())
    assert_jacobians_match(plane_factor(X(0), L(1), coeffs, UNIT3), values)
    assert_jacobians_match(anchored_plane_factor(X(0), A(0), L(0), coeffs, UNIT3), values)


def test_anchored_and_global_factor_agree_on_the_same_plane() -> None:
    rng = np.random.default_rng(7)
    pose = random_pose(rng)
    plane_world = random_plane(rng)
    T_wa = anchor_pose(np.array([40.0, -10.0, 0.0]))
    plane_a = plane_world.transform(gtsam.Pose3(T_wa))
    measured = np.asarray(
        plane_world.transform(pose).retract([0.01, -0.02, 0.03]).planeCoefficients()
    )
    values = gtsam.Values()
    values.insert(X(0), pose)
    values.insert(A(0), gtsam.Pose3(T_wa))
    values.insert(L(0), plane_a)
    values.insert(L(1), plane_world)
    e_global = plane_factor(X(0), L(1), measured, UNIT3).unwhitenedError(values)
    e_local = anchored_plane_factor(X(0), A(0), L(0), measured, UNIT3).unwhitenedError(values)
    # Same magnitude of mismatch; the two factors differ only in the basis / sign convention.
    assert np.linalg.norm(e_global) == pytest.approx(np.linalg.norm(e_local), rel=1e-3)
    assert anchor_prior(A(0), T_wa).unwhitenedError(values) == pytest.approx(np.zeros(6))


def test_predict_plane_matches_gtsam_transform() -> None:
    rng = np.random.default_rng(3)
    pose, plane = random_pose(rng), random_plane(rng)
    expected = np.asarray(plane.transform(pose).planeCoefficients())
    got = predict_plane(pose.matrix(), np.asarray(plane.planeCoefficients()))
    np.testing.assert_allclose(got, expected, atol=1e-9)


def test_flipped_normal_is_silent_in_oriented_plane3_then_guarded() -> None:
    """OrientedPlane3's normal error of a flipped measurement is zero: verify, then guard."""
    values = gtsam.Values()
    values.insert(X(0), gtsam.Pose3())
    values.insert(L(0), gtsam.OrientedPlane3(1.0, 0.0, 0.0, -5.0))
    values.insert(L(1), gtsam.OrientedPlane3(1.0, 0.0, 0.0, 0.0))  # through the sensor
    true_far = np.array([1.0, 0.0, 0.0, -5.0])
    true_through = np.array([1.0, 0.0, 0.0, 0.0])
    e_far = plane_factor(X(0), L(0), -true_far, UNIT3).unwhitenedError(values)
    e_through = plane_factor(X(0), L(1), -true_through, UNIT3).unwhitenedError(values)
    # The silent failure: a 180 degree normal error shows as zero normal error ...
    np.testing.assert_allclose(e_far[:2], 0.0, atol=1e-12)
    assert abs(e_far[2]) == pytest.approx(10.0)  # ... only the offset (2 d) notices,
    np.testing.assert_allclose(e_through, 0.0, atol=1e-12)  # ... or nothing at all.
    # The guard: the measurement is turned back to agree with the prediction.
    for truth in (true_far, true_through):
        fixed, flipped = orient_measurement(-truth, truth)
        assert flipped
        np.testing.assert_allclose(fixed, truth)
        same, flipped = orient_measurement(truth, truth)
        assert not flipped and same is truth


def _far_graph(offset: float, anchored: bool) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
    """PR #680's situation: one pose ``offset`` m out, two horizontal planes, all with priors.

    The pose starts 1 m off its optimum; every factor is exact at the optimum.
    """
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    truth = gtsam.Pose3(gtsam.Rot3(), np.array([offset - 1.0, 0.0, 0.0]))
    graph.add(gtsam.PriorFactorPose3(X(0), truth, gtsam.noiseModel.Isotropic.Sigma(6, 0.01)))
    values.insert(X(0), gtsam.Pose3(gtsam.Rot3(), np.array([offset, 0.0, 0.0])))
    plane_sigma = gtsam.noiseModel.Isotropic.Sigma(3, 0.005)
    T_wa = anchor_pose(np.array([offset, 0.0, 0.0]))
    for j, height in enumerate((-2.0, 3.0)):
        world = gtsam.OrientedPlane3(0.0, 0.0, 1.0, -height)
        measured = np.asarray(world.transform(truth).planeCoefficients())
        if anchored:
            values.insert(A(j), gtsam.Pose3(T_wa))
            graph.add(anchor_prior(A(j), T_wa))
            local = world.transform(gtsam.Pose3(T_wa))
            values.insert(L(j), local)
            graph.add(anchored_plane_factor(X(0), A(j), L(j), measured, plane_sigma))
            graph.add(anchored_plane_factor(X(0), A(j), L(j), measured, plane_sigma))
        else:
            values.insert(L(j), world)
            graph.add(plane_factor(X(0), L(j), measured, plane_sigma))
            graph.add(plane_factor(X(0), L(j), measured, plane_sigma))
    return graph, values


def _hessian_condition(graph: gtsam.NonlinearFactorGraph, values: gtsam.Values) -> float:
    H, _ = graph.linearize(values).hessian()
    return float(np.linalg.cond(H))


def test_anchored_planes_are_well_conditioned_far_from_the_origin() -> None:
    near = _hessian_condition(*_far_graph(1.0, anchored=False))
    far_global = _hessian_condition(*_far_graph(1000.0, anchored=False))
    far_anchored = _hessian_condition(*_far_graph(1000.0, anchored=True))
    assert far_global > 1e3 * near  # grows with the squared lever arm
    assert far_anchored < 10 * _hessian_condition(*_far_graph(1.0, anchored=True))
    graph, values = _far_graph(1000.0, anchored=True)
    result = gtsam.LevenbergMarquardtOptimizer(graph, values).optimize()
    np.testing.assert_allclose(result.atPose3(X(0)).translation(), [999.0, 0, 0], atol=1e-6)


def test_error_vector_sign_convention_and_plane_noise_whitening() -> None:
    """errorVector = [normal part like localCoordinates, offset part negated]; plane_noise
    turns the tangent covariance into the covariance of that error (MC check)."""
    rng = np.random.default_rng(21)
    measured = gtsam.OrientedPlane3(np.array([0.6, 0.64, 0.48, 3.0]))
    for k in range(3):
        v = np.zeros(3)
        v[k] = 1e-3
        e = measured.errorVector(measured.retract(v))
        np.testing.assert_allclose(e, [1e-3, 0, 0] if k == 0 else [0, 1e-3, 0] if k == 1
                                   else [0, 0, -1e-3], atol=1e-8)  # fmt: skip
    cov = np.array([[4e-6, 0.0, 1.5e-5], [0.0, 1e-6, 0.0], [1.5e-5, 0.0, 1e-4]])
    noise = plane_noise(cov)
    values = gtsam.Values()
    values.insert(X(0), gtsam.Pose3())
    values.insert(A(0), gtsam.Pose3())
    factor = anchored_plane_factor(X(0), A(0), L(0), measured.planeCoefficients(), noise)
    squares = []
    for xi in rng.multivariate_normal(np.zeros(3), cov, size=400):
        # The truth is the measurement moved back by the noise.
        truth = measured.retract(-xi)
        trial = gtsam.Values(values)
        trial.insert(L(0), truth)
        squares.append(2.0 * factor.error(trial))
    assert 2.7 < np.mean(squares) < 3.3  # chi2(3) mean; the wrong sign gives 7.4
