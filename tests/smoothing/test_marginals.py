"""Pose marginals by the Schur complement (planodom.smoothing.marginals) against gtsam, and
with undetermined variables against a numpy inverse of the determined ones."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from planodom.config import SmoothingConfig
from planodom.smoothing.batch import group_by_epoch
from planodom.smoothing.graph import GraphBuilder, X
from planodom.smoothing.marginals import (
    FIRST_POSE_TIGHTENING,
    determined_pose_marginals,
    pose_covariances,
    pose_marginals,
    schur_preferred,
)
from planodom.smoothing.synthetic import make_sequence
from planodom_factors.pose5 import pose5_factor

NOISE = dict(sigma_rotation=1e-3, sigma_translation=0.01, sigma_normal=0.005, sigma_offset=0.01)


@pytest.mark.parametrize("plane_factor", ["anchored", "global"])
def test_schur_marginals_are_gtsams(plane_factor: str) -> None:
    graph, values, builder = _built(25, 3, plane_factor)
    assert builder.stats.plane_factors > 50
    zero = values.zeroVectors()
    dims = {key: zero.at(key).size for key in values.keys()}
    ours = pose_marginals(graph.linearize(values), [X(k) for k in range(25)], dims)
    marginals = gtsam.Marginals(graph, values)
    theirs = np.stack([marginals.marginalCovariance(X(k)) for k in range(25)])
    scale = np.linalg.norm(theirs, axis=(1, 2))[:, None, None]
    np.testing.assert_allclose(ours / scale, theirs / scale, atol=1e-7)
    np.testing.assert_allclose(ours, np.swapaxes(ours, 1, 2))


def test_an_undetermined_landmark_raises() -> None:
    """A landmark with no information (a factor of zero weight) is refused, not inverted."""
    linear = gtsam.GaussianFactorGraph()
    unit = gtsam.noiseModel.Unit
    linear.add(X(0), np.eye(6), np.zeros(6), unit.Create(6))
    L = gtsam.symbol_shorthand.L(0)
    linear.add(X(0), np.zeros((3, 6)), L, np.zeros((3, 3)), np.zeros(3), unit.Create(3))
    with pytest.raises(np.linalg.LinAlgError):
        pose_marginals(linear, [X(0)], {L: 3})


def test_schur_is_preferred_where_the_landmarks_hold_most_dimensions() -> None:
    poses = {X(k): 6 for k in range(10)}
    few = poses | {gtsam.symbol_shorthand.L(j): 3 for j in range(5)}
    many = poses | {gtsam.symbol_shorthand.L(j): 3 for j in range(25)}
    assert not schur_preferred(10, few)
    assert schur_preferred(10, many)


def _dense(linear: gtsam.GaussianFactorGraph, keys: list[int]) -> np.ndarray:
    """The information matrix of ``linear`` in the order of ``keys`` (numpy, dense)."""
    ordering = gtsam.Ordering()
    for key in keys:
        ordering.push_back(key)
    A, _ = linear.jacobian(ordering)
    return A.T @ A


def _built(
    n: int, seed: int, plane_factor: str
) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values, GraphBuilder]:
    """The graph, values and builder of a simulated sequence of ``n`` epochs."""
    seq = make_sequence(n, seed=seed, **NOISE)
    builder = GraphBuilder(SmoothingConfig(plane_factor=plane_factor, robust_planes=False))
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    by_epoch = group_by_epoch(seq.relatives, len(seq.planes))
    for k, planes in enumerate(seq.planes):
        update = builder.add_epoch(planes, by_epoch[k])
        graph.push_back(update.factors)
        values.insert(update.values)
    return graph, values, builder


def _builder_graph(n: int) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
    graph, values, _ = _built(n, 5, "anchored")
    return graph, values


def test_an_undetermined_landmark_is_left_out_exactly() -> None:
    """A landmark whose third direction no factor observes: it is named, and the poses'
    marginals are those of a numpy inverse of the information without that direction."""
    graph, values = _builder_graph(12)
    linear = graph.linearize(values)
    zero = values.zeroVectors()
    dims = {key: zero.at(key).size for key in values.keys()}
    rng = np.random.default_rng(0)
    L = gtsam.symbol_shorthand.L(99)
    A_l = np.zeros((2, 3))
    A_l[:, :2] = 400.0 * np.eye(2)  # observes directions 0 and 1 only
    for k in (3, 7):
        A_x = 400.0 * rng.normal(size=(2, 6))
        linear.add(X(k), A_x, L, A_l, np.zeros(2), gtsam.noiseModel.Unit.Create(2))
    dims[L] = 3
    poses = [X(k) for k in range(12)]
    ours = determined_pose_marginals(linear, poses, dims)
    assert ours.dropped == [L] and not ours.undetermined
    others = [key for key in values.keys() if key not in poses]
    H = _dense(linear, poses + others + [L])
    keep = np.arange(len(H) - 1)  # L's undetermined direction is its last coordinate
    cov = np.linalg.inv(H[np.ix_(keep, keep)])
    theirs = np.stack([cov[6 * k : 6 * k + 6, 6 * k : 6 * k + 6] for k in range(12)])
    scale = np.linalg.norm(theirs, axis=(1, 2))[:, None, None]
    np.testing.assert_allclose(ours.covariances / scale, theirs / scale, atol=1e-8)
    with pytest.raises(np.linalg.LinAlgError):  # the plain Schur path refuses it
        pose_marginals(linear, poses, dims)


def test_an_undetermined_pose_axis_is_nan_and_named() -> None:
    """A pose tied by a 5-DoF factor only (no vertical factor): its height is free (its
    column of the Jacobian exactly zero: no rotation to the first pose, the identity);
    gtsam's elimination fails, the covariances come from the fallback with NaN on that
    axis, and every other pose's marginal is a numpy inverse's without that axis."""
    graph, values = _builder_graph(8)
    last = X(8)
    step = gtsam.Pose3(gtsam.Rot3(), np.array([0.5, 0.2, 0.0]))
    assert np.array_equal(values.atPose3(X(0)).matrix(), np.eye(4))
    values.insert(last, step)
    graph.add(pose5_factor(X(0), last, step))
    covariances, note = pose_covariances(graph, values, 9, relative_to_first=True)
    assert note is not None and "epochs 8 (axes [5])" in note
    assert np.isnan(covariances[8][5]).all() and np.isnan(covariances[8][:, 5]).all()
    assert np.isfinite(covariances[:8]).all() and np.isfinite(covariances[8][:5, :5]).all()
    linear = graph.linearize(values)
    linear.add(X(0), FIRST_POSE_TIGHTENING / 1e-4 * np.eye(6), np.zeros(6),
               gtsam.noiseModel.Unit.Create(6))  # fmt: skip
    with pytest.raises(RuntimeError):  # what the batch reported before: no covariances
        linear.eliminateMultifrontal(gtsam.Ordering.MetisNonlinearFactorGraph(graph))
    poses = [X(k) for k in range(9)]
    others = [key for key in values.keys() if key not in poses]
    H = _dense(linear, poses + others)
    keep = np.delete(np.arange(len(H)), 6 * 8 + 5)  # the free height
    cov = np.linalg.inv(H[np.ix_(keep, keep)])
    theirs = np.stack([cov[6 * k : 6 * k + 6, 6 * k : 6 * k + 6] for k in range(8)])
    scale = np.linalg.norm(theirs, axis=(1, 2))[:, None, None]
    np.testing.assert_allclose(covariances[1:8] / scale[1:], theirs[1:] / scale[1:], atol=1e-6)
    free = cov[48:53, 48:53]
    scale8 = np.linalg.norm(free)
    np.testing.assert_allclose(covariances[8][:5, :5] / scale8, free / scale8, atol=1e-8)


def test_the_dense_fallback_is_bounded_in_size(monkeypatch) -> None:
    """Over ``DENSE_MAX_POSE_DIM`` pose dimensions the fallback is not tried: the error
    says so (the batch then reports the covariances unavailable, as before it)."""
    import planodom.smoothing.marginals as marginals

    graph, values = _builder_graph(8)
    step = gtsam.Pose3(gtsam.Rot3(), np.array([0.5, 0.2, 0.0]))
    values.insert(X(8), step)
    graph.add(pose5_factor(X(0), X(8), step))
    monkeypatch.setattr(marginals, "DENSE_MAX_POSE_DIM", 6 * 9 - 1)
    with pytest.raises(RuntimeError, match="54 pose dimensions are over"):
        pose_covariances(graph, values, 9, relative_to_first=True)
    monkeypatch.setattr(marginals, "DENSE_MAX_POSE_DIM", 6 * 9)
    covariances, note = pose_covariances(graph, values, 9, relative_to_first=True)
    assert note is not None and np.isfinite(covariances[:8]).all()
