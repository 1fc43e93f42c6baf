"""Loop factors' share of their older epoch's deskewing error in the sandwich
(``sandwich_loop_sources`` "deskew", planodom.smoothing.loop_deskew): the map against a
nonlinear refit of the relative pose from perturbed planes and the factor's own whitened
error, and the sandwich with it against a dense computation."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from dense_sandwich import assert_sandwich_equals_dense, odometry_chain, whitened_jacobian
from scipy.linalg import sqrtm
from scipy.optimize import least_squares

from planodom.config import PlanodomConfig, SmoothingConfig
from planodom.errors import ConfigError
from planodom.geometry import Plane, transform_planes
from planodom.se3 import se3_exp
from planodom.smoothing.graph import X
from planodom.smoothing.loop_deskew import loop_deskew_maps, relative_pose_change
from planodom.smoothing.loop_records import LoopFactor
from planodom.smoothing.sandwich import sandwich_covariances
from planodom_factors.pose5 import pose5_factor

E = 6  # poses X0..X5; steps delta 1, loop factors X0-X4 and X0-X5


def _cov(rng: np.random.Generator, n: np.ndarray) -> np.ndarray:
    """A random rank-3 (4, 4) covariance of ``(n, d)``: no variance along ``n`` itself."""
    P = np.eye(4)
    P[:3, :3] -= np.outer(n, n)
    A = rng.normal(size=(4, 4)) * [1e-3, 1e-3, 1e-3, 1e-2]
    return P @ (A @ A.T + 1e-6 * np.eye(4)) @ P


def _old_planes(rng: np.random.Generator) -> list[Plane]:
    """Five planes of the older epoch with deskewing Jacobians that keep normals unit."""
    normals = rng.normal(size=(5, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    out = []
    for n, d in zip(normals, rng.uniform(-8.0, 8.0, 5), strict=True):
        P = np.eye(4)
        P[:3, :3] -= np.outer(n, n)
        out.append(Plane(n, float(d), _cov(rng, n), deskew_jacobian=P @ rng.normal(size=(4, 6))))
    return out


def _seen_from(rng: np.random.Generator, planes_a: list[Plane], T_a_b: np.ndarray) -> list[Plane]:
    """``planes_a`` seen from frame b (exactly ``T_a_b``), with their own covariances."""
    normals = np.stack([p.normal for p in planes_a])
    n_b, d_b = transform_planes(
        np.linalg.inv(T_a_b), normals, np.array([p.offset for p in planes_a])
    )
    return [Plane(n, float(d), _cov(rng, n)) for n, d in zip(n_b, d_b, strict=True)]


def _refit(T_a_b: np.ndarray, planes_a: list[Plane], planes_b: list[Plane], shift: np.ndarray):
    """(4, 4) the relative pose refitted (scipy, nonlinear) to a's planes moved by their
    Jacobians times ``shift`` (6,), weighted by both planes' covariances."""
    moved = []
    for p in planes_a:
        c = p.coefficients + p.deskew_jacobian @ shift
        moved.append(c / np.linalg.norm(c[:3]))
    roots = []
    for pa, pb in zip(planes_a, planes_b, strict=True):
        J = np.eye(4)
        J[:3, :3], J[3, :3] = T_a_b[:3, :3], -(T_a_b[:3, 3] @ T_a_b[:3, :3])
        W = np.linalg.pinv(pa.covariance + J @ pb.covariance @ J.T, rcond=1e-9, hermitian=True)
        roots.append(np.real(sqrtm(W)))

    def residual(xi: np.ndarray) -> np.ndarray:
        T = T_a_b @ se3_exp(xi)
        out = []
        for c, pb, L in zip(moved, planes_b, roots, strict=True):
            n, d = transform_planes(T, pb.normal[None], np.array([pb.offset]))
            out.append(L @ (c - np.append(n[0], d[0])))
        return np.concatenate(out)

    xi = least_squares(residual, np.zeros(6), xtol=1e-15, ftol=1e-15, gtol=1e-15).x
    return T_a_b @ se3_exp(xi)


def _lap() -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values, list[LoopFactor], dict]:
    """A chain of poses with between factors and two 5-DoF loop factors from X0, each
    solved from five plane pairs."""
    rng = np.random.default_rng(5)
    step = gtsam.Pose3(gtsam.Rot3.RzRyRx(0.02, -0.01, 0.9), gtsam.Point3(2.0, 0.5, 0.05))
    graph, values = odometry_chain(rng, step, E)
    planes: dict[int, list[Plane]] = {0: _old_planes(rng)}
    loops = []
    for b in (4, 5):
        T = values.atPose3(X(0)).between(values.atPose3(X(b))).matrix()
        T = T @ se3_exp(rng.normal(0.0, 0.003, 6))  # measured: not the estimate
        planes[b] = _seen_from(rng, planes[0], T)
        A = rng.normal(size=(5, 5)) * 0.01
        noise = gtsam.noiseModel.Gaussian.Covariance(A @ A.T + 1e-5 * np.eye(5))
        graph.add(pose5_factor(X(0), X(b), T, noise))
        pairs = np.column_stack([np.arange(5), np.arange(5)])
        loops.append(LoopFactor(b, 0, T, A @ A.T, 5, graph.size() - 1, associations=pairs))
    return graph, values, loops, planes


def test_map_is_the_refit_factors_whitened_error_change() -> None:
    graph, values, loops, planes = _lap()
    Q = np.zeros((E, 6, 6))
    Q[0] = np.eye(6)
    index = {i: i for i in range(graph.size())}
    f = loops[1]
    maps = loop_deskew_maps(graph, values, loops, index, planes, Q)
    column, g = maps[f.factor]
    assert column == 0 and g.shape == (5, 6)
    factor = graph.at(f.factor)
    base = factor.whitenedError(values)
    for c, eps in enumerate((2e-5, -3e-5, 1e-5, 4e-5, -2e-5, 3e-5)):
        shift = np.zeros(6)
        shift[c] = eps
        T = _refit(f.T_old_curr, planes[0], planes[f.epoch], shift)
        moved = pose5_factor(X(0), X(f.epoch), T, factor.noiseModel())
        change = (moved.whitenedError(values) - base) / eps
        np.testing.assert_allclose(g[:, c], change, rtol=2e-3, atol=2e-3 * np.abs(g).max())


def test_relative_pose_change_none_without_jacobians() -> None:
    T = np.eye(4)
    p = Plane(np.array([1.0, 0.0, 0.0]), 1.0, np.diag([0.0, 1e-6, 1e-6, 1e-4]))
    assert relative_pose_change(T, [p], [p], np.array([[0, 0]])) is None


def test_sandwich_with_loop_maps_in_the_epochs_column_equals_the_dense() -> None:
    graph, values, loops, planes = _lap()
    Q = np.zeros((E, 6, 6))
    A = np.random.default_rng(9).normal(size=(6, 6)) * 0.02
    Q[0] = A @ A.T
    index = {i: i for i in range(graph.size())}
    f0, f1 = loops
    maps = loop_deskew_maps(graph, values, loops, index, planes, Q)
    assert sorted(maps) == [f0.factor, f1.factor]
    extra = (maps, np.zeros((0, 6, 6)))
    out, _ = sandwich_covariances(graph, values, E, {}, Q, False, 1e-3, extra)
    J, rows = whitened_jacobian(graph, values, E)
    G = np.zeros((J.shape[0], 6))  # one column block: epoch 0's change of motion
    for i, (_, g) in maps.items():
        G[rows[i] : rows[i + 1]] = g
    assert_sandwich_equals_dense(out.covariances[:E], J, G, Q[0])


def test_option_value_deskew() -> None:
    assert SmoothingConfig().sandwich_loop_sources == "independent"
    cfg = PlanodomConfig().updated({"smoothing.sandwich_loop_sources": "deskew"})
    assert cfg.smoothing.sandwich_loop_sources == "deskew"
    with pytest.raises(ConfigError, match="sandwich_loop_sources"):
        PlanodomConfig().updated({"smoothing.sandwich_loop_sources": "nonsense"})
