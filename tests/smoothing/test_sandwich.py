"""Sandwich covariances (planodom.smoothing.sandwich) against finite differences, a dense
inverse and the Monte-Carlo covariance of the estimator."""

from __future__ import annotations

from collections.abc import Callable

import gtsam
import numpy as np
import pytest
import scipy.sparse as sp

import planodom.smoothing.sandwich as sandwich_module
import planodom.smoothing.sparse_sandwich as sparse_sandwich
from planodom.config import PlanodomConfig, SmoothingConfig
from planodom.errors import ConfigError
from planodom.geometry import Plane
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.graph import A, L, X
from planodom.smoothing.marginals import POSE_DIM, pose_marginals
from planodom.smoothing.run import smoothing_config
from planodom.smoothing.sandwich import (
    CHUNK_ROWS,
    _dense_pose_covariances,
    _mirror_upper,
    _scaled_columns,
    plane_error_map,
    sandwich_covariances,
    sandwich_pose_covariances,
)
from planodom.smoothing.synthetic import make_sequence, with_deskew_jacobians
from planodom_factors.planes import (
    anchored_plane_factor,
    plane_factor,
    plane_noise,
    predict_plane,
)


def _rotation(rng: np.random.Generator, scale: float) -> gtsam.Rot3:
    return gtsam.Rot3.Expmap(rng.normal(scale=scale, size=3))


def _perturbed(coeffs: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """(4,) plane ``coeffs`` + ``delta`` in (n, d), the normal renormalised."""
    n = coeffs[:3] + delta[:3]
    return np.append(n / np.linalg.norm(n), coeffs[3] + delta[3])


def _world() -> tuple[list[gtsam.Pose3], np.ndarray]:
    """Six poses along a short curve and five world planes (walls, floor, slanted)."""
    rng = np.random.default_rng(3)
    poses = [
        gtsam.Pose3(_rotation(rng, 0.05).compose(gtsam.Rot3.Yaw(0.1 * k)),
                    np.array([0.8 * k, 0.1 * k * k, 0.02 * k]))
        for k in range(6)
    ]  # fmt: skip
    normals = np.array([[0, 0, 1.0], [1, 0.1, 0], [-0.2, 1, 0], [0.7, -0.7, 0.1], [-1, 0, 0.2]])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    offsets = np.array([1.5, 4.0, 3.0, 5.0, 7.0])
    return poses, np.column_stack([normals, offsets])


@pytest.mark.parametrize("kind", ["global", "anchored"])
def test_error_map_is_the_whitened_errors_change(kind: str) -> None:
    """plane_error_map equals the finite difference of the factor's whitened error when
    the measured plane moves by its deskew_jacobian times a change of motion."""
    rng = np.random.default_rng(1)
    poses, walls = _world()
    T = poses[2]
    measured = predict_plane(T.matrix(), walls[3])
    values = gtsam.Values()
    values.insert(X(0), T)
    M = rng.normal(size=(3, 3))
    noise = plane_noise(M @ M.T * 1e-5 + np.eye(3) * 1e-6)
    if kind == "global":
        values.insert(L(0), gtsam.OrientedPlane3(walls[3]))

        def make(z: np.ndarray) -> gtsam.NonlinearFactor:
            return plane_factor(X(0), L(0), z, noise)
    else:
        Ta = gtsam.Pose3(gtsam.Rot3(), np.array([1.0, -2.0, 0.5]))
        values.insert(A(0), Ta)
        values.insert(L(0), gtsam.OrientedPlane3(predict_plane(Ta.matrix(), walls[3])))

        def make(z: np.ndarray) -> gtsam.NonlinearFactor:
            return anchored_plane_factor(X(0), A(0), L(0), z, noise)

    jac = rng.normal(scale=0.05, size=(4, 6))
    plane = Plane(measured[:3], float(measured[3]), deskew_jacobian=jac)
    G = plane_error_map(make(measured), plane)
    assert G is not None
    h = 1e-6
    for j in range(6):
        dxi = np.zeros(6)
        dxi[j] = h
        moved = make(_perturbed(measured, jac @ dxi)).whitenedError(values)
        base = make(measured).whitenedError(values)
        np.testing.assert_allclose((moved - base) / h, G[:, j], rtol=1e-4, atol=1e-4)


def _graph(
    poses: list[gtsam.Pose3], walls: np.ndarray, measured: dict[tuple[int, int], np.ndarray],
    between: list[gtsam.Pose3], plane_sigmas: np.ndarray, between_sigma: float,
    own_covariance: Callable[[int, Plane], np.ndarray] | None = None,
) -> tuple[gtsam.NonlinearFactorGraph, dict[int, tuple[int, Plane]], gtsam.Values]:  # fmt: skip
    """A graph: prior on X(0), between factors, a global plane factor per (pose, wall);
    ``own_covariance(k, plane)`` (3, 3), when given, is added to each plane factor's noise."""
    graph = gtsam.NonlinearFactorGraph()
    graph.add(gtsam.PriorFactorPose3(X(0), poses[0], gtsam.noiseModel.Isotropic.Sigma(6, 1e-6)))
    for k, Z in enumerate(between):
        noise = gtsam.noiseModel.Isotropic.Sigma(6, between_sigma)
        graph.add(gtsam.BetweenFactorPose3(X(k), X(k + 1), Z, noise))
    planes: dict[int, tuple[int, Plane]] = {}
    noise = plane_noise(np.diag(plane_sigmas**2))
    for (k, j), z in measured.items():
        plane = Plane(z[:3], float(z[3]), deskew_jacobian=_jacobians()[j])
        planes[graph.size()] = (k, plane)
        if own_covariance is not None:
            noise = plane_noise(np.diag(plane_sigmas**2) + own_covariance(k, plane))
        graph.add(plane_factor(X(k), L(j), z, noise))
    values = gtsam.Values()
    for k, T in enumerate(poses):
        values.insert(X(k), T)
    for j, w in enumerate(walls):
        values.insert(L(j), gtsam.OrientedPlane3(w))
    return graph, planes, values


def _jacobians() -> np.ndarray:
    """(5, 4, 6) fixed deskewing Jacobians of the five walls."""
    return np.random.default_rng(7).normal(scale=0.5, size=(5, 4, 6))


@pytest.mark.parametrize("gaps", [False, True])
def test_pose_space_equals_dense_sandwich(gaps: bool) -> None:
    """The pose blocks from the landmarks' Schur complement equal the dense
    ``A^-1 (A + B Q B^T) A^-1`` of the whole linearised system; the fitted blocks equal
    pose_marginals'. ``gaps``: two walls not seen by a middle pose (a landmark's poses
    not contiguous in the poses' information)."""
    poses, walls = _world()
    measured = {(k, j): predict_plane(T.matrix(), w) for k, T in enumerate(poses)
                for j, w in enumerate(walls)}  # fmt: skip
    if gaps:
        del measured[(1, 0)], measured[(3, 2)]
    between = [poses[k].between(poses[k + 1]) for k in range(len(poses) - 1)]
    graph, planes, values = _graph(
        poses, walls, measured, between, np.array([1e-3, 1e-3, 5e-3]), 0.05
    )
    linear = graph.linearize(values)
    zero = values.zeroVectors()
    dims = {key: zero.at(key).size for key in values.keys()}
    rng = np.random.default_rng(2)
    maps = {i: (k, plane_error_map(graph.at(i), p)) for i, (k, p) in planes.items()}
    Q = np.stack([np.diag(rng.uniform(1e-6, 1e-4, size=6)) for _ in poses])
    keys = [X(k) for k in range(len(poses))]
    out = sandwich_pose_covariances(linear, keys, dims, maps, Q)

    ordering = gtsam.Ordering()
    for key in keys + [L(j) for j in range(len(walls))]:
        ordering.push_back(key)
    J = linear.jacobian(ordering)[0]
    offsets, row = {}, 0
    for i in range(linear.size()):
        offsets[i] = row
        row += linear.at(i).jacobian()[0].shape[0]
    H = J.T @ J
    B = np.zeros((J.shape[1], 6 * len(poses)))
    for i, (k, g) in maps.items():
        assert g is not None
        B[:, 6 * k : 6 * k + 6] += J[offsets[i] : offsets[i] + 3].T @ g
    Qfull = np.zeros((6 * len(poses), 6 * len(poses)))
    for k, q in enumerate(Q):
        Qfull[6 * k : 6 * k + 6, 6 * k : 6 * k + 6] = q
    Hinv = np.linalg.inv(H)
    cov = Hinv + Hinv @ B @ Qfull @ B.T @ Hinv
    for k in range(len(poses)):
        s = np.s_[6 * k : 6 * k + 6]
        np.testing.assert_allclose(out.covariances[k], cov[s, s], rtol=1e-6, atol=1e-14)
        np.testing.assert_allclose(out.fitted[k], Hinv[s, s], rtol=1e-6, atol=1e-14)
    np.testing.assert_allclose(
        out.fitted, pose_marginals(linear, keys, dims), rtol=1e-6, atol=1e-14
    )
    assert np.all(np.diagonal(out.covariances - out.fitted, axis1=1, axis2=2)[1:] > 0)


def _mixed_system(
    extra_pose: bool = False,
) -> tuple[gtsam.GaussianFactorGraph, list[int], dict[int, int], dict, np.ndarray]:
    """The linearised system of ``_graph``'s world with walls 3 and 4 as anchored
    landmarks (anchors without a prior: each group has undetermined directions), between
    factors, and the error maps; ``extra_pose``: a seventh pose key no factor touches."""
    poses, walls = _world()
    rng = np.random.default_rng(4)
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    graph.add(gtsam.PriorFactorPose3(X(0), poses[0], gtsam.noiseModel.Isotropic.Sigma(6, 1e-4)))
    for k in range(len(poses) - 1):
        noise = gtsam.noiseModel.Isotropic.Sigma(6, 0.05)
        graph.add(gtsam.BetweenFactorPose3(X(k), X(k + 1), poses[k].between(poses[k + 1]), noise))
    for k, T in enumerate(poses):
        values.insert(X(k), T)
    anchors = {3: poses[1], 4: poses[2]}
    for j, w in enumerate(walls):
        if j in anchors:
            values.insert(A(j), anchors[j])
            values.insert(L(j), gtsam.OrientedPlane3(predict_plane(anchors[j].matrix(), w)))
        else:
            values.insert(L(j), gtsam.OrientedPlane3(w))
    maps = {}
    for k, T in enumerate(poses):
        for j, w in enumerate(walls):
            z = predict_plane(T.matrix(), w)
            M = rng.normal(size=(3, 3))
            noise = plane_noise(M @ M.T * 1e-5 + np.eye(3) * 1e-6)
            factor = (anchored_plane_factor(X(k), A(j), L(j), z, noise) if j in anchors
                      else plane_factor(X(k), L(j), z, noise))  # fmt: skip
            plane = Plane(z[:3], float(z[3]), deskew_jacobian=rng.normal(scale=0.3, size=(4, 6)))
            maps[graph.size()] = (k, plane_error_map(factor, plane))
            graph.add(factor)
    linear = graph.linearize(values)
    zero = values.zeroVectors()
    dims = {key: zero.at(key).size for key in values.keys()}
    keys = [X(k) for k in range(len(poses))] + ([X(len(poses))] if extra_pose else [])
    Q = np.stack([np.diag(rng.uniform(1e-6, 1e-4, size=6)) for _ in keys])
    return linear, keys, dims, maps, Q


@pytest.mark.parametrize(("node_width", "merge_width"), [(1, 0), (4, 0), (48, 24)])
def test_selected_inversion_equals_the_dense_path(
    node_width: int, merge_width: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The sparse selected inversion and its derivative give the dense path's sandwich
    and fitted blocks (global and anchored landmarks, the anchors' undetermined
    directions left out), whatever the blocks' widths."""
    monkeypatch.setattr(sparse_sandwich, "SELECTED_INVERSION", True)
    monkeypatch.setattr(sparse_sandwich, "NODE_WIDTH", node_width)
    monkeypatch.setattr(sparse_sandwich, "MERGE_WIDTH", merge_width)
    linear, keys, dims, maps, Q = _mixed_system()
    dense = _dense_pose_covariances(linear, keys, dims, maps, Q)
    fast = sandwich_pose_covariances(linear, keys, dims, maps, Q)
    assert dense.undetermined == {} and fast.undetermined == {}
    for got, want in ((fast.covariances, dense.covariances), (fast.fitted, dense.fitted)):
        sd = np.sqrt(np.diagonal(want, axis1=1, axis2=2))
        np.testing.assert_allclose(got / (sd[:, :, None] * sd[:, None, :]),
                                   want / (sd[:, :, None] * sd[:, None, :]), atol=1e-9)  # fmt: skip
    assert np.all(np.diagonal(fast.covariances - fast.fitted, axis1=1, axis2=2)[1:] > 0)


def test_pose_block_with_structural_zeros(monkeypatch: pytest.MonkeyPatch) -> None:
    """A pose whose own 6 x 6 information block has structural zeros (its rotation and
    its translation tied to the last pose by separate factors) still gets its whole,
    correlated covariance block: equal to the dense path's."""
    monkeypatch.setattr(sparse_sandwich, "SELECTED_INVERSION", True)
    linear, keys, dims, maps, Q = _mixed_system()
    rng = np.random.default_rng(9)
    extra = X(len(keys))
    unit = gtsam.noiseModel.Unit.Create(3)
    eye, zero = np.eye(3), np.zeros((3, 3))
    for A_extra in (np.hstack([eye, zero]), np.hstack([zero, eye])):  # X(5)'s errors, mapped
        linear.add(extra, 1e3 * A_extra, keys[-1], 1e3 * rng.normal(size=(3, 6)), np.zeros(3), unit)
    keys, dims = keys + [extra], dims | {extra: 6}
    Q = np.concatenate([Q, Q[-1:]])
    fast = sandwich_pose_covariances(linear, keys, dims, maps, Q)
    dense = _dense_pose_covariances(linear, keys, dims, maps, Q)
    assert np.any(np.abs(dense.fitted[-1][:3, 3:]) > 1e-3 * np.abs(dense.fitted[-1]).max())
    np.testing.assert_allclose(fast.fitted, dense.fitted, rtol=1e-8, atol=1e-14)
    np.testing.assert_allclose(fast.covariances, dense.covariances, rtol=1e-8, atol=1e-14)


def _ill_conditioned_chain(
    anchor: float, nodes: int = 60, columns: int = 4
) -> tuple[sp.csc_matrix, sp.csc_matrix, np.ndarray]:
    """A Jacobi-scaled information ``K`` (6 nodes-dims each) of a chain of 6-dof nodes
    tied to their neighbours and every fourth to the third next (random weights), held in
    place only by a prior of weight ``anchor`` on the first (condition 9e10 at 1e-4, as
    the worse conditioned laps' 6e9), and ``R = K V`` with ``V`` (N, 6 columns) of unit
    size on one node per block of 6 columns: ``K^-1 R = V`` although ``K^-1`` is large,
    the cancellation of the sandwich's extra term (its columns in the range of the
    whitened Jacobian's transpose)."""
    rng = np.random.default_rng(3)
    N = POSE_DIM * nodes
    rows = []

    def tie(i: int, j: int, weight: np.ndarray) -> None:
        row = np.zeros((POSE_DIM, N))
        row[:, POSE_DIM * i : POSE_DIM * (i + 1)] = -weight
        row[:, POSE_DIM * j : POSE_DIM * (j + 1)] = weight
        rows.append(row)

    for i in range(nodes - 1):
        tie(i, i + 1, np.eye(POSE_DIM) + 0.3 * rng.normal(size=(POSE_DIM, POSE_DIM)))
        if i % 4 == 0 and i + 3 < nodes:
            tie(i, i + 3, 0.5 * rng.normal(size=(POSE_DIM, POSE_DIM)))
    prior = np.zeros((POSE_DIM, N))
    prior[:, :POSE_DIM] = anchor * np.eye(POSE_DIM)
    J = np.vstack(rows + [prior])
    K = J.T @ J
    d = np.sqrt(np.diag(K))
    K /= np.outer(d, d)
    V = np.zeros((N, POSE_DIM * columns))
    for k, node in enumerate(rng.choice(nodes, size=columns, replace=False)):
        V[POSE_DIM * node : POSE_DIM * (node + 1), POSE_DIM * k : POSE_DIM * (k + 1)] = rng.normal(
            size=(POSE_DIM, POSE_DIM)
        )
    return sp.csc_matrix(K), sp.csc_matrix(K @ V), V


@pytest.mark.skipif(sparse_sandwich.EXTENDED is None, reason="no extended precision")
@pytest.mark.parametrize("node_width", [1, 6, 48])
def test_selected_inversion_of_an_ill_conditioned_system(
    node_width: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """On a system as ill-conditioned as world 2's at 6 mm: the extra term
    ``K^-1 R R^T K^-1`` is ``V V^T`` (closed form) and ``K^-1``'s blocks a refined dense
    inverse's to 1e-7 of the standard deviations at every block width (measured 1e-9).
    The first sparse version was off by 2-3e-6 in the extra term (``R R^T`` rounded to
    double, the recursion in double) and by 8-9e-6 in the fitted blocks with
    multi-column blocks (the Schur update through an explicit inverse of ill-conditioned
    pivot blocks; 1.2e-6 with one-column blocks)."""
    monkeypatch.setattr(sparse_sandwich, "NODE_WIDTH", node_width)
    K, R, V = _ill_conditioned_chain(1e-4)
    N = K.shape[0]
    E = N // POSE_DIM
    wanted = sp.block_diag([np.ones((POSE_DIM, POSE_DIM))] * E, format="csc")
    Z = sparse_sandwich._selected_inverse(K, R, wanted)
    pos = np.arange(N).reshape(E, POSE_DIM)
    values, derivative = Z.entries(pos[:, :, None], pos[:, None, :])
    fitted, extra = values.astype(float), -derivative.astype(float)
    dense = np.linalg.inv(K.toarray())  # one step of refinement, residual in long double
    residual = np.eye(N) - (K.toarray().astype(np.longdouble) @ dense.astype(np.longdouble))
    dense = dense + dense @ residual.astype(float)
    idx = np.arange(N).reshape(E, POSE_DIM)
    want_fitted = dense[idx[:, :, None], idx[:, None, :]]
    VV = V @ V.T
    want_extra = VV[idx[:, :, None], idx[:, None, :]]
    sd = np.sqrt(np.diagonal(want_fitted + want_extra, axis1=1, axis2=2))
    sd_fitted = np.sqrt(np.diagonal(want_fitted, axis1=1, axis2=2))
    assert np.max(np.abs(extra - want_extra) / (sd[:, :, None] * sd[:, None, :])) < 1e-7
    err = np.abs(fitted - want_fitted) / (sd_fitted[:, :, None] * sd_fitted[:, None, :])
    assert np.max(err) < 1e-7


def test_undetermined_pose_takes_the_dense_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """A pose key no factor touches: the sparse path stops at its pivot, the dense path
    names its six axes and sets them NaN; the other poses' blocks as without it."""
    monkeypatch.setattr(sparse_sandwich, "SELECTED_INVERSION", True)
    linear, keys, dims, maps, Q = _mixed_system(extra_pose=True)
    out = sandwich_pose_covariances(linear, keys, dims, maps, Q)
    assert out.undetermined == {len(keys) - 1: [0, 1, 2, 3, 4, 5]}
    assert np.all(np.isnan(out.covariances[-1]))
    ref = sandwich_pose_covariances(linear, keys[:-1], dims, maps, Q[:-1])
    np.testing.assert_allclose(out.covariances[:-1], ref.covariances, rtol=1e-7, atol=1e-14)


def _monte_carlo_covariances(  # noqa: PLR0913
    make_graph, poses, truth, rel, sig_plane, sig_between, Q, values, n=400, seed=11
):  # noqa: ANN001, ANN202
    """The solved poses' covariance (E, 6, 6) over ``n`` seeded samples: each plane moved by
    one change of motion per epoch (``Q``) through its deskewing Jacobian and by its fit
    noise, each relative pose by its noise; ``make_graph(measured, between)`` the graph."""
    rng = np.random.default_rng(seed)
    jac = _jacobians()
    errors = []
    for _ in range(n):
        dxi = [rng.multivariate_normal(np.zeros(6), q) for q in Q]
        measured = {}
        for (k, j), z in truth.items():
            z = _perturbed(z, jac[j] @ dxi[k])
            fit = rng.normal(size=3) * sig_plane
            measured[(k, j)] = np.asarray(gtsam.OrientedPlane3(z).retract(fit).planeCoefficients())
        between = [Z.compose(gtsam.Pose3.Expmap(rng.normal(size=6) * sig_between)) for Z in rel]
        est = gtsam.LevenbergMarquardtOptimizer(make_graph(measured, between), values).optimize()
        errors.append([est.atPose3(X(k)).localCoordinates(poses[k]) for k in range(len(poses))])
    err = np.array(errors)  # (n, E, 6)
    return np.einsum("ski,skj->kij", err, err) / len(err)


def test_sandwich_is_the_estimators_monte_carlo_covariance() -> None:
    """Planes perturbed by their fit noise plus one change of motion per epoch through
    their deskewing Jacobians: the solved poses' covariance (400 seeded samples) matches
    the sandwich covariance (diagonal within 20 %), and is well above the fitted one."""
    poses, walls = _world()
    truth = {(k, j): predict_plane(T.matrix(), w) for k, T in enumerate(poses)
             for j, w in enumerate(walls)}  # fmt: skip
    rel = [poses[k].between(poses[k + 1]) for k in range(len(poses) - 1)]
    sig_plane, sig_between = np.array([2e-4, 2e-4, 1e-3]), 0.05
    Q = np.stack([np.diag([1e-6] * 3 + [4e-6] * 3) * (1 + k) for k in range(len(poses))])
    graph, planes, values = _graph(poses, walls, truth, rel, sig_plane, sig_between)
    out, note = sandwich_covariances(graph, values, len(poses), planes, Q, False, 1e-6)
    assert note is None

    def make_graph(measured, between):  # noqa: ANN001, ANN202
        return _graph(poses, walls, measured, between, sig_plane, sig_between)[0]

    mc = _monte_carlo_covariances(make_graph, poses, truth, rel, sig_plane, sig_between, Q, values)
    for k in range(1, len(poses)):
        var_mc, var_sw = np.diag(mc[k]), np.diag(out.covariances[k])
        np.testing.assert_allclose(var_mc, var_sw, rtol=0.2)
        assert np.all(var_mc > 2.0 * np.diag(out.fitted[k]))


@pytest.mark.parametrize("spread", [True, False])
def test_batch_sandwich_keeps_the_poses(spread: bool) -> None:
    """smooth_batch with covariance_model "sandwich": the same poses as "fitted"; the
    covariances grow where the epochs' motion changes (scans spread in time) and are the
    fitted ones, bit for bit, for scans taken at one instant."""
    seq = make_sequence(30, seed=4, sigma_rotation=2e-4, sigma_translation=5e-3,
                        sigma_normal=1e-3, sigma_offset=5e-3)  # fmt: skip
    planes, relatives = with_deskew_jacobians(seq, spread=spread)
    base = SmoothingConfig(loop_closure=False, covariance_model="fitted")
    fitted = smooth_batch(planes, relatives, base)
    sandwich = smooth_batch(
        planes, relatives, base.model_copy(update={"covariance_model": "sandwich"})
    )
    assert np.array_equal(fitted.poses, sandwich.poses)
    assert fitted.covariances is not None and sandwich.covariances is not None
    grown = np.diagonal(sandwich.covariances - fitted.covariances, axis1=1, axis2=2)[1:]
    if spread:
        assert np.all(grown > -1e-9 * np.diagonal(fitted.covariances, axis1=1, axis2=2)[1:])
        assert np.median(grown / np.diagonal(fitted.covariances, axis1=1, axis2=2)[1:]) > 0.1
    else:
        assert np.array_equal(fitted.covariances, sandwich.covariances)


def test_sandwich_config() -> None:
    """The sandwich switches the planes' deskewing Jacobians on; "auto", the default, has
    the batch smoothing switch them on for its odometry (unless the noise models hold the
    deskewing error or are rescaled), and leaves a run without smoothing without them;
    "sandwich" refuses noise models that already hold the deskewing error or are rescaled."""
    cfg = PlanodomConfig.from_dict({"smoothing": {"covariance_model": "fitted"}})
    assert not cfg.extraction.deskew_jacobian
    assert not smoothing_config(cfg).extraction.deskew_jacobian
    assert cfg.updated({"smoothing.covariance_model": "sandwich"}).extraction.deskew_jacobian
    assert not PlanodomConfig().extraction.deskew_jacobian
    assert smoothing_config(PlanodomConfig()).extraction.deskew_jacobian
    off = PlanodomConfig.from_dict({"extraction": {"deskew_jacobian": False}})
    assert smoothing_config(off).extraction.deskew_jacobian  # an earlier run's config.yaml
    for field, value in (("deskew_noise", "twist_change"), ("covariance_scale", "groups")):
        cfg = PlanodomConfig.from_dict({"smoothing": {field: value}})
        assert cfg.smoothing.covariance_model == "auto"
        assert not smoothing_config(cfg).extraction.deskew_jacobian
    for field, value in (("deskew_noise", "twist_change_jacobian"), ("covariance_scale", "groups")):
        with pytest.raises(ConfigError, match="covariance_model"):
            SmoothingConfig(covariance_model="sandwich", **{field: value})


def test_mirror_upper_over_several_chunks() -> None:
    """The in-place mirror equals the upper triangle and its transpose (n over two chunks)."""
    a = np.random.default_rng(5).normal(size=(2 * CHUNK_ROWS + 7, 2 * CHUNK_ROWS + 7))
    expected = np.triu(a) + np.triu(a, 1).T
    _mirror_upper(a)
    assert np.array_equal(a, expected)


@pytest.mark.parametrize("dense_fraction", [0.0, 2.0])
def test_scaled_columns_dense_and_sparse(
    dense_fraction: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``diag(s) B~ blockdiag(L)`` from overlapping blocks, in the dense and the sparse
    form, equals the product of the explicitly summed matrices."""
    rng = np.random.default_rng(11)
    n_poses, n_epochs = 5, 4
    parts, B = [], np.zeros((6 * n_poses, 6 * n_epochs))
    for _ in range(7):
        poses = np.sort(rng.choice(n_poses, size=rng.integers(1, 4), replace=False))
        rows = np.concatenate([6 * p + np.arange(6) for p in poses])
        epochs = rng.choice(n_epochs, size=rng.integers(1, 3), replace=False)
        block = rng.normal(size=(len(rows), 6 * len(epochs)))
        col_of = {int(k): 6 * j for j, k in enumerate(epochs)}
        parts.append((rows, col_of, block))
        for k, c in col_of.items():
            B[np.ix_(rows, 6 * k + np.arange(6))] += block[:, c : c + 6]
    roots = [rng.normal(size=(6, 6)) for _ in range(n_epochs)]
    scale = rng.uniform(0.5, 2.0, size=6 * n_poses)
    R = np.zeros((6 * n_epochs, 6 * n_epochs))
    for k, root in enumerate(roots):
        R[6 * k : 6 * k + 6, 6 * k : 6 * k + 6] = root
    monkeypatch.setattr(sandwich_module, "DENSE_FRACTION", dense_fraction)
    out = _scaled_columns(parts, 6 * n_poses, roots, scale)
    assert isinstance(out, np.ndarray) == (dense_fraction < 1.0)
    dense = out if isinstance(out, np.ndarray) else out.toarray()
    np.testing.assert_allclose(dense, (scale[:, None] * B) @ R, rtol=1e-12, atol=1e-12)


@pytest.mark.skipif(sparse_sandwich.EXTENDED is None, reason="no extended precision")
def test_selected_inversion_stores_the_factors_pattern_only() -> None:
    """The selected inversion's panels hold the factor's (padded) entries, not ``N x N``:
    every stored entry equals a refined dense inverse's (and the extra term ``V V^T``,
    closed form) to 1e-7 of the standard deviations, and an entry outside the pattern is
    refused."""
    K, R, V = _ill_conditioned_chain(1e-2)
    N = K.shape[0]
    wanted = sp.block_diag([np.ones((POSE_DIM, POSE_DIM))] * (N // POSE_DIM), format="csc")
    Z = sparse_sandwich._selected_inverse(K, R, wanted)
    panels = Z.panels
    assert panels.offset[-1] < N * N / 4
    rows = np.concatenate(
        [np.repeat(np.concatenate([np.arange(c0, c1), b]), c1 - c0) for c0, c1, b in panels.nodes]
    )
    cols = np.concatenate(
        [np.tile(np.arange(c0, c1), c1 - c0 + len(b)) for c0, c1, b in panels.nodes]
    )
    lower = rows >= cols
    assert len(rows) == panels.offset[-1]
    dense = np.linalg.inv(K.toarray())
    residual = np.eye(N) - (K.toarray().astype(np.longdouble) @ dense.astype(np.longdouble))
    dense = dense + dense @ residual.astype(float)
    VV = V @ V.T
    variable = np.argsort(Z.position)  # the variable at each position
    i, j = variable[rows[lower]], variable[cols[lower]]
    sd = np.sqrt(np.diag(dense) + np.diag(VV))
    fitted = Z.values[lower].astype(float)
    extra = -Z.derivative[lower].astype(float)
    assert np.max(np.abs(fitted - dense[i, j]) / (sd[i] * sd[j])) < 1e-7
    assert np.max(np.abs(extra - VV[i, j]) / (sd[i] * sd[j])) < 1e-7
    c0, c1, below = panels.nodes[0]
    outside = np.setdiff1d(np.arange(N), np.concatenate([np.arange(c0, c1), below]))
    with pytest.raises(ValueError, match="outside"):
        panels.index(np.array([outside[-1]]), np.array([c0]))


@pytest.mark.skipif(sparse_sandwich.EXTENDED is None, reason="no extended precision")
def test_selected_inversion_of_a_long_loop() -> None:
    """A loop of 3 000 variables, where the M-matrix's numeric factor underflows fill
    entries to zero (LAP14: lap 366 at 6 mm stopped on "an entry outside the factor's
    pattern"): the inverse's diagonal and the extra term ``V V^T`` (closed form) against
    a dense inverse to 1e-9 of the standard deviations."""
    n = 3000
    A = sp.diags([np.ones(n - 1), np.ones(n - 1)], [-1, 1], shape=(n, n), format="lil")
    A[0, n - 1] = A[n - 1, 0] = 1.0
    K = sp.csc_matrix(2.5 * sp.identity(n) - A)
    V = np.zeros((n, 2))
    V[[0, 1500], [0, 1]] = 1.0
    R = sp.csc_matrix(K @ V)
    Z = sparse_sandwich._selected_inverse(K, R, sp.identity(n, format="csc"))
    i = np.arange(n)
    values, derivative = Z.entries(i, i)
    want = np.diag(np.linalg.inv(K.toarray()))
    want_extra = (V**2).sum(axis=1)
    sd = np.sqrt(want + want_extra)
    assert np.max(np.abs(values.astype(float) - want) / sd**2) < 1e-9
    assert np.max(np.abs(-derivative.astype(float) - want_extra) / sd**2) < 1e-9


def test_negative_variance_takes_the_dense_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """The selected inversion is not rank-revealing: on a system near singular its pivots
    pass and its variances come out negative (LAP14: lap 366 at 6 mm, condition 7e15). A
    variance not positive hands over to the dense path: the result is the dense path's."""
    linear, keys, dims, maps, Q = _mixed_system()
    monkeypatch.setattr(sparse_sandwich, "SELECTED_INVERSION", False)
    dense = sandwich_pose_covariances(linear, keys, dims, maps, Q)
    monkeypatch.setattr(sparse_sandwich, "SELECTED_INVERSION", True)
    original = sparse_sandwich._selected_inverse

    def negated(*args: object) -> object:
        Z = original(*args)  # type: ignore[arg-type]
        Z.values = -Z.values
        return Z

    monkeypatch.setattr(sparse_sandwich, "_selected_inverse", negated)
    out = sandwich_pose_covariances(linear, keys, dims, maps, Q)
    np.testing.assert_array_equal(out.covariances, dense.covariances)
