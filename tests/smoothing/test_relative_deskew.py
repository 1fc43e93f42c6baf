"""Both ends' deskewing errors of a relative-pose factor (planodom.smoothing.relative_deskew):
each end's first-order change of the fitted relative pose against a nonlinear refit
(scipy) of the relative pose from planes moved by their deskewing Jacobians, the factor
maps against the refit factor's own whitened error, and the sandwich with two terms per
factor against a dense computation."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from dense_sandwich import assert_sandwich_equals_dense, whitened_jacobian
from scipy.linalg import sqrtm
from scipy.optimize import least_squares

from planodom.config import PlanodomConfig, SmoothingConfig
from planodom.errors import ConfigError
from planodom.geometry import Plane, transform_planes
from planodom.odometry.relative import RelativePose, Status
from planodom.se3 import se3_exp, se3_log
from planodom.smoothing.graph import X
from planodom.smoothing.loop_records import LoopFactor
from planodom.smoothing.relative_deskew import pair_fit_changes, relative_error_maps
from planodom.smoothing.sandwich import batch_sandwich, sandwich_covariances
from planodom_factors.pose5 import pose5_factor, rotation_factor


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
    """Six planes of epoch a and the same seen from b (exactly ``T_a_b``), each with its
    own covariance and deskewing Jacobian."""
    normals = rng.normal(size=(6, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    offsets = rng.uniform(-8.0, 8.0, 6)
    a = [Plane(n, float(d), _cov(rng, n), deskew_jacobian=_jacobian(rng, n))
         for n, d in zip(normals, offsets, strict=True)]  # fmt: skip
    n_b, d_b = transform_planes(np.linalg.inv(T_a_b), normals, offsets)
    b = [Plane(n, float(d), _cov(rng, n), deskew_jacobian=_jacobian(rng, n))
         for n, d in zip(n_b, d_b, strict=True)]  # fmt: skip
    return a, b


def _moved(planes: list[Plane], shift: np.ndarray) -> list[np.ndarray]:
    out = []
    for p in planes:
        c = p.coefficients + p.deskew_jacobian @ shift
        out.append(c / np.linalg.norm(c[:3]))
    return out


def _refit(T_a_b: np.ndarray, a: list[Plane], b: list[Plane], shift_a, shift_b) -> np.ndarray:  # noqa: ANN001
    """(6,) right tangent of the relative pose refitted (nonlinear least squares) to a's
    planes moved by ``shift_a`` and b's by ``shift_b``, weighted by both planes'
    covariances as at ``T_a_b``."""
    ca, cb = _moved(a, shift_a), _moved(b, shift_b)
    roots = []
    for pa, pb in zip(a, b, strict=True):
        J = np.eye(4)
        J[:3, :3], J[3, :3] = T_a_b[:3, :3], -(T_a_b[:3, 3] @ T_a_b[:3, :3])
        W = np.linalg.pinv(pa.covariance + J @ pb.covariance @ J.T, rcond=1e-9, hermitian=True)
        roots.append(np.real(sqrtm(W)))

    def residual(xi: np.ndarray) -> np.ndarray:
        T = T_a_b @ se3_exp(xi)
        out = []
        for x, y, L in zip(ca, cb, roots, strict=True):
            n, d = transform_planes(T, y[None, :3], np.array([y[3]]))
            out.append(L @ (x - np.append(n[0], d[0])))
        return np.concatenate(out)

    return least_squares(residual, np.zeros(6), xtol=1e-15, ftol=1e-15, gtol=1e-15).x


@pytest.mark.parametrize("end", [0, 1])
def test_each_end_is_the_nonlinear_refit(end: int) -> None:
    rng = np.random.default_rng(3 + end)
    T = se3_exp(np.array([0.02, -0.01, 0.4, 1.5, 0.3, 0.05]))
    a, b = _epochs(rng, T)
    pairs = np.column_stack([np.arange(6), np.arange(6)])
    M = pair_fit_changes(T, a, b, pairs)[end]
    assert M is not None and M.shape == (6, 6)
    base = _refit(T, a, b, np.zeros(6), np.zeros(6))
    np.testing.assert_allclose(base, 0.0, atol=1e-9)  # the planes agree with T exactly
    for c, eps in enumerate((2e-5, -3e-5, 1e-5, 4e-5, -2e-5, 3e-5)):
        shift = np.zeros(6)
        shift[c] = eps
        shifts = (shift, np.zeros(6)) if end == 0 else (np.zeros(6), shift)
        xi = se3_log(se3_exp(_refit(T, a, b, *shifts)))
        np.testing.assert_allclose(M[:, c], xi / eps, rtol=2e-3, atol=2e-3 * np.abs(M).max())


def test_an_end_without_jacobians_does_not_move() -> None:
    rng = np.random.default_rng(8)
    T = se3_exp(np.array([0.0, 0.0, 0.3, 1.0, 0.0, 0.0]))
    a, b = _epochs(rng, T)
    still = [Plane(p.normal, p.offset, p.covariance) for p in b]
    pairs = np.column_stack([np.arange(6), np.arange(6)])
    M_a, M_b = pair_fit_changes(T, a, still, pairs)
    assert M_a is not None and M_b is None
    assert pair_fit_changes(T, a, b, np.zeros((0, 2), dtype=int)) == (None, None)


def _chain() -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values, list[RelativePose], dict]:
    """Poses X0..X3 each seeing six planes (their own Jacobians), a prior on X0, a 5-DoF
    step per neighbour and a rotation-only step X1-X3, measured where the planes are; the
    estimate is off the poses; weak priors on X1..X3 hold z."""
    rng = np.random.default_rng(11)
    step = se3_exp(np.array([0.01, -0.02, 0.3, 1.2, 0.2, 0.03]))
    values, graph = gtsam.Values(), gtsam.NonlinearFactorGraph()
    poses = [np.eye(4)]
    for _ in range(3):
        poses.append(poses[-1] @ step)
    for k, T in enumerate(poses):
        values.insert(X(k), gtsam.Pose3(T @ se3_exp(rng.normal(0.0, 0.002, 6))))
        if k:  # weak: the steps leave z undetermined
            weak = gtsam.noiseModel.Isotropic.Sigma(6, 0.5)
            graph.add(gtsam.PriorFactorPose3(X(k), gtsam.Pose3(T), weak))
    graph.add(
        gtsam.PriorFactorPose3(X(0), gtsam.Pose3(), gtsam.noiseModel.Isotropic.Sigma(6, 1e-3))
    )
    normals = rng.normal(size=(6, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    offsets = rng.uniform(-8.0, 8.0, 6)
    planes = {}
    for k, T in enumerate(poses):
        n_k, d_k = transform_planes(np.linalg.inv(T), normals, offsets)
        planes[k] = [Plane(n, float(d), _cov(rng, n), deskew_jacobian=_jacobian(rng, n))
                     for n, d in zip(n_k, d_k, strict=True)]  # fmt: skip
    pairs = np.column_stack([np.arange(6), np.arange(6)])
    rels = []
    for a, b in ((0, 1), (1, 2), (2, 3), (1, 3)):
        T = np.linalg.inv(poses[a]) @ poses[b]  # the planes' own: the estimate is off
        A = rng.normal(size=(5, 5)) * 0.01
        status = Status.DEGENERATE if (a, b) == (1, 3) else Status.OK
        rel = RelativePose(T, A @ A.T + 1e-5 * np.eye(5), status, pairs, prev=a, curr=b)
        rels.append(rel)
        make, dim = (pose5_factor, 5) if status is Status.OK else (rotation_factor, 3)
        cov = (A @ A.T + 1e-5 * np.eye(5))[:dim, :dim]
        graph.add(make(X(a), X(b), T, gtsam.noiseModel.Gaussian.Covariance(cov)))
    return graph, values, rels, planes


def test_factor_maps_are_the_refit_factors_whitened_error_change() -> None:
    graph, values, rels, planes = _chain()
    Q = np.tile(np.eye(6), (4, 1, 1))
    index = {i: i for i in range(graph.size())}
    maps = relative_error_maps(graph, values, Q, 3, index, ((), planes), rels)
    assert sorted(maps) == [4, 5, 6, 7]  # every step, not the priors
    for i, rel in zip((4, 5, 6, 7), rels, strict=True):
        factor = graph.at(i)
        terms = dict(maps[i])
        assert sorted(terms) == [rel.prev, rel.curr]
        base = factor.whitenedError(values)
        make = pose5_factor if factor.dim() == 5 else rotation_factor
        for end, epoch in enumerate((rel.prev, rel.curr)):
            for c, eps in enumerate((2e-5, -3e-5, 1e-5, 4e-5, -2e-5, 3e-5)):
                shifts = [np.zeros(6), np.zeros(6)]
                shifts[end][c] = eps
                T = rel.T_prev_curr @ se3_exp(
                    _refit(rel.T_prev_curr, planes[rel.prev], planes[rel.curr], *shifts)
                )
                moved = make(X(rel.prev), X(rel.curr), T, factor.noiseModel())
                change = (moved.whitenedError(values) - base) / eps
                g = terms[epoch]
                np.testing.assert_allclose(g[:, c], change, rtol=2e-3, atol=2e-3 * np.abs(g).max())


def test_sandwich_with_both_ends_equals_the_dense() -> None:
    graph, values, rels, planes = _chain()
    rng = np.random.default_rng(2)
    Q = np.stack([(lambda A: A @ A.T)(rng.normal(size=(6, 6)) * 0.02) for _ in range(4)])
    index = {i: i for i in range(graph.size())}
    maps = relative_error_maps(graph, values, Q, 3, index, ((), planes), rels)
    out, _ = sandwich_covariances(graph, values, 4, {}, Q, False, 1e-3, (maps, np.zeros((0, 6, 6))))
    J, rows = whitened_jacobian(graph, values, 4)
    G = np.zeros((J.shape[0], 24))  # one column block per epoch
    for i, terms in maps.items():
        for k, g in terms:
            G[rows[i] : rows[i + 1], 6 * k : 6 * k + 6] += g
    S = np.zeros((24, 24))
    for k in range(4):
        S[6 * k : 6 * k + 6, 6 * k : 6 * k + 6] = Q[k]
    assert_sandwich_equals_dense(list(out.covariances), J, G, S)


def test_loops_value_maps_the_loop_factors_ends_alone() -> None:
    """``sandwich_relative_ends`` "loops": a loop factor X0-X3 (beyond ``delta_max`` 2)
    beside the chain's steps; the batch's sandwich equals the dense one whose maps are
    "both"'s rows of the loop factor only (fails if a step's map or the loop's is lost)."""
    graph, values, rels, planes = _chain()
    pairs = np.column_stack([np.arange(6), np.arange(6)])
    T = values.atPose3(X(0)).inverse().compose(values.atPose3(X(3))).matrix()
    T = T @ se3_exp(np.array([1e-3, -2e-3, 1e-3, 0.01, -0.02, 0.0]))
    cov = np.diag([1e-5, 2e-5, 1e-5, 1e-4, 2e-4])
    loop = LoopFactor(3, 0, T, cov, 6, graph.size(), associations=pairs)
    graph.add(pose5_factor(X(0), X(3), T, gtsam.noiseModel.Gaussian.Covariance(cov)))
    rng = np.random.default_rng(5)
    Q = np.stack([(lambda A: A @ A.T)(rng.normal(size=(6, 6)) * 0.02) for _ in range(4)])
    index = {i: i for i in range(graph.size())}
    maps = relative_error_maps(graph, values, Q, 2, index, ([loop], planes), rels)
    assert loop.factor in maps and len(maps) > 1  # "both" maps the steps too
    J, rows = whitened_jacobian(graph, values, 4)
    S = np.zeros((24, 24))
    for k in range(4):
        S[6 * k : 6 * k + 6, 6 * k : 6 * k + 6] = Q[k]
    for value, kept in (("loops", [loop.factor]), ("both", list(maps))):
        cfg = SmoothingConfig(
            delta_max=2,
            sandwich_relative_ends=value,
            prior_sigma=1e-3,
            covariances_relative_to_first=False,
        )
        out, _ = batch_sandwich(cfg, graph, graph, {}, Q, values, ([loop], planes), (rels, ()))
        G = np.zeros((J.shape[0], 24))
        for i in kept:
            for k, g in maps[i]:
                G[rows[i] : rows[i + 1], 6 * k : 6 * k + 6] += g
        assert_sandwich_equals_dense(list(out), J, G, S)


def test_option_value_both() -> None:
    assert SmoothingConfig().sandwich_relative_ends == "none"
    cfg = PlanodomConfig().updated({"smoothing.sandwich_relative_ends": "both"})
    assert cfg.smoothing.sandwich_relative_ends == "both"
    assert PlanodomConfig().updated({"smoothing.sandwich_relative_ends": "loops"}) is not None
    with pytest.raises(ConfigError, match="sandwich_relative_ends"):
        PlanodomConfig().updated({"smoothing.sandwich_relative_ends": "older"})
