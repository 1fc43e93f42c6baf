"""Loop factors sharing their planes' fit errors in the sandwich (``sandwich_loop_sources``
"planes", planodom.smoothing.loop_planes): the per-plane change of the relative pose
against a nonlinear refit with that plane moved, and the batch sandwich with the option
against a dense ``A^-1 J^T S J A^-1`` whose ``S`` is written out from the planes' errors
(each factor's own block the identity, the blocks between factors the shared planes')."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from dense_sandwich import odometry_chain, whitened_jacobian
from scipy.linalg import sqrtm
from scipy.optimize import least_squares

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import Plane, transform_planes
from planodom.se3 import se3_exp
from planodom.smoothing.graph import X
from planodom.smoothing.loop_planes import loop_plane_maps, pair_fit_plane_changes
from planodom.smoothing.loop_records import LoopFactor
from planodom.smoothing.sandwich import batch_sandwich
from planodom_factors.pose5 import pose5_factor

E = 6  # poses X0..X5; steps delta 1, loop factors X0-X4 and X0-X5


def _cov(rng: np.random.Generator, n: np.ndarray) -> np.ndarray:
    """A random rank-3 (4, 4) covariance of ``(n, d)``: no variance along ``n`` itself."""
    P = np.eye(4)
    P[:3, :3] -= np.outer(n, n)
    A = rng.normal(size=(4, 4)) * [1e-3, 1e-3, 1e-3, 1e-2]
    return P @ (A @ A.T + 1e-6 * np.eye(4)) @ P


def _planes(rng: np.random.Generator) -> list[Plane]:
    normals = rng.normal(size=(5, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return [
        Plane(n, float(d), _cov(rng, n))
        for n, d in zip(normals, rng.uniform(-8, 8, 5), strict=True)
    ]


def _seen_from(rng: np.random.Generator, planes_a: list[Plane], T_a_b: np.ndarray) -> list[Plane]:
    normals = np.stack([p.normal for p in planes_a])
    n_b, d_b = transform_planes(
        np.linalg.inv(T_a_b), normals, np.array([p.offset for p in planes_a])
    )
    return [Plane(n, float(d), _cov(rng, n)) for n, d in zip(n_b, d_b, strict=True)]


def _refit(T_a_b, planes_a, planes_b, moved_a, moved_b) -> np.ndarray:  # noqa: ANN001
    """(6,) the right-tangent change of the relative pose refitted (scipy, nonlinear) to
    the planes' coefficients ``moved_a`` / ``moved_b`` (lists of (4,)), weighted by both
    planes' covariances at ``T_a_b``."""
    J = np.eye(4)
    J[:3, :3], J[3, :3] = T_a_b[:3, :3], -(T_a_b[:3, 3] @ T_a_b[:3, :3])
    roots = [
        np.real(sqrtm(np.linalg.pinv(pa.covariance + J @ pb.covariance @ J.T, rcond=1e-9,
                                     hermitian=True)))
        for pa, pb in zip(planes_a, planes_b, strict=True)
    ]  # fmt: skip

    def residual(xi: np.ndarray) -> np.ndarray:
        T = T_a_b @ se3_exp(xi)
        out = []
        for ca, cb, L in zip(moved_a, moved_b, roots, strict=True):
            n, d = transform_planes(T, cb[None, :3], np.array([cb[3]]))
            out.append(L @ (ca - np.append(n[0], d[0])))
        return np.concatenate(out)

    return least_squares(residual, np.zeros(6), xtol=1e-15, ftol=1e-15, gtol=1e-15).x


@pytest.mark.parametrize("end", ["a", "b"])
def test_plane_change_is_the_refit(end: str) -> None:
    rng = np.random.default_rng(3)
    T = se3_exp(np.array([0.02, -0.01, 0.7, 3.0, 1.0, 0.1]))
    pa = _planes(rng)
    pb = _seen_from(rng, pa, T)
    pairs = np.column_stack([np.arange(5), np.arange(5)])
    changes = pair_fit_plane_changes(T, pa, pb, pairs)
    assert changes is not None and len(changes) == 10
    for p in (0, 3):
        M = changes[(end, p)]
        own = pa if end == "a" else pb
        basis = np.linalg.svd(own[p].covariance)[0][:, :3]  # the plane's own directions
        for c in range(3):
            eps = 1e-5
            moved_a = [q.coefficients.copy() for q in pa]
            moved_b = [q.coefficients.copy() for q in pb]
            (moved_a if end == "a" else moved_b)[p] = own[p].coefficients + eps * basis[:, c]
            xi = _refit(T, pa, pb, moved_a, moved_b)
            np.testing.assert_allclose(
                M @ basis[:, c], xi / eps, rtol=2e-3, atol=2e-3 * np.abs(M).max()
            )


def _lap() -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values, list[LoopFactor], dict]:
    """A chain with two 5-DoF loop factors from X0, each solved from epoch 0's five
    planes (the same planes: their errors are shared)."""
    rng = np.random.default_rng(5)
    step = gtsam.Pose3(gtsam.Rot3.RzRyRx(0.02, -0.01, 0.9), gtsam.Point3(2.0, 0.5, 0.05))
    graph, values = odometry_chain(rng, step, E)
    planes: dict[int, list[Plane]] = {0: _planes(rng)}
    loops = []
    for b in (4, 5):
        T = values.atPose3(X(0)).between(values.atPose3(X(b))).matrix()
        T = T @ se3_exp(rng.normal(0.0, 0.003, 6))
        planes[b] = _seen_from(rng, planes[0], T)
        A = rng.normal(size=(5, 5)) * 0.01
        noise = gtsam.noiseModel.Gaussian.Covariance(A @ A.T + 1e-5 * np.eye(5))
        graph.add(pose5_factor(X(0), X(b), T, noise))
        pairs = np.column_stack([np.arange(5), np.arange(5)])
        loops.append(LoopFactor(b, 0, T, A @ A.T, 5, graph.size() - 1, associations=pairs))
    return graph, values, loops, planes


def test_batch_sandwich_equals_dense_with_shared_planes() -> None:
    graph, values, loops, planes = _lap()
    cfg = PlanodomConfig().updated({"smoothing.sandwich_loop_sources": "planes"}).smoothing
    Q = np.zeros((E, 6, 6))
    Q[2] = 1e-4 * np.eye(6)  # a column no factor maps into: the sandwich runs, adds nothing
    index = {i: i for i in range(graph.size())}
    out, _ = batch_sandwich(cfg, graph, graph, {}, Q, values, (loops, planes))
    J, rows = whitened_jacobian(graph, values, E)
    # S written out: each loop factor's whitened error = R E (sum over its planes of
    # dxi/dpi * e_pi) + own noise; its own block stays I, the cross block is the planes'.
    maps, cols = loop_plane_maps(graph, values, loops, index, planes, {}, E)
    assert set(maps) == {f.factor for f in loops} and len(cols) == 15  # 5 planes of epochs 0, 4, 5
    S = np.eye(J.shape[0])
    f0, f1 = (f.factor for f in loops)
    cross = np.zeros((5, 5))
    terms0, terms1 = dict(maps[f0]), dict(maps[f1])
    for c in set(terms0) & set(terms1):
        cross += terms0[c] @ cols[c - E] @ terms1[c].T
    assert len(set(terms0) & set(terms1)) == 5  # epoch 0's planes, shared
    S[rows[f0] : rows[f0 + 1], rows[f1] : rows[f1 + 1]] = cross
    S[rows[f1] : rows[f1 + 1], rows[f0] : rows[f0 + 1]] = cross.T
    # the prior on X0 is tightened in the sandwich as in sandwich_covariances
    A_inv = np.linalg.inv(J.T @ J + _tightening(cfg))
    dense = A_inv @ J.T @ S @ J @ A_inv
    for k in range(E):
        block = dense[6 * k : 6 * k + 6, 6 * k : 6 * k + 6]
        np.testing.assert_allclose(out[k], block, rtol=1e-6, atol=1e-14)
    independent = batch_sandwich(
        cfg.model_copy(update={"sandwich_loop_sources": "independent"}), graph, graph, {}, Q,
        values, (loops, planes),
    )[0]  # fmt: skip
    assert not np.allclose(out[-1], independent[-1], rtol=1e-3)


def _tightening(cfg) -> np.ndarray:  # noqa: ANN001
    from planodom.smoothing.marginals import FIRST_POSE_TIGHTENING

    out = np.zeros((6 * E, 6 * E))
    if cfg.covariances_relative_to_first:
        out[:6, :6] = (FIRST_POSE_TIGHTENING / cfg.prior_sigma) ** 2 * np.eye(6)
    return out


def test_option_value_planes() -> None:
    cfg = PlanodomConfig().updated({"smoothing.sandwich_loop_sources": "planes"})
    assert cfg.smoothing.sandwich_loop_sources == "planes"
    with pytest.raises(ConfigError, match="sandwich_loop_sources"):
        PlanodomConfig().updated({"smoothing.sandwich_loop_sources": "plane"})
