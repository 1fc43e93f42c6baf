"""The batched evaluation of the 5-DoF, rotation and vertical factors: the same errors and
linear factors as gtsam's own evaluation of the graph, bit for bit."""

from __future__ import annotations

import gtsam
import numpy as np
from scipy.spatial.transform import Rotation

from planodom import geometry as g
from planodom_factors import pose5
from planodom_factors.batched import BatchedResiduals
from planodom_factors.pose5 import pose5_factor, rotation_factor, vertical_factor

X = gtsam.symbol_shorthand.X
L = gtsam.symbol_shorthand.L


def _transform(rng: np.random.Generator, angle: float, scale: float) -> np.ndarray:
    R = Rotation.from_rotvec(angle * Rotation.random(random_state=rng).as_rotvec()).as_matrix()
    return g.make_transform(R, rng.uniform(-scale, scale, 3))


def _graph(rng: np.random.Generator, n: int) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
    """A chain of n poses with every kind of factor: 5-DoF (Gaussian, full covariance and
    robust), rotation, vertical, a prior and a plane landmark (C++ factors), and one
    5-DoF factor whose rotation error exceeds 90 degrees (the kernel defers to gtsam)."""
    values = gtsam.Values()
    poses = [np.eye(4)]
    for _ in range(n - 1):
        poses.append(poses[-1] @ _transform(rng, 0.2, 2.0))
    for k, T in enumerate(poses):
        values.insert(X(k), gtsam.Pose3(T))
    values.insert(L(0), gtsam.OrientedPlane3(np.array([0.0, 0.0, 1.0, 1.5])))
    cov = np.diag(rng.uniform(1e-4, 1e-2, 5))
    cov[0, 3] = cov[3, 0] = 0.5 * np.sqrt(cov[0, 0] * cov[3, 3])
    gaussian = gtsam.noiseModel.Gaussian.Covariance(cov)
    robust = gtsam.noiseModel.Robust.Create(
        gtsam.noiseModel.mEstimator.Cauchy.Create(2.0), gaussian
    )
    graph = gtsam.NonlinearFactorGraph()
    graph.add(gtsam.PriorFactorPose3(X(0), gtsam.Pose3(), gtsam.noiseModel.Isotropic.Sigma(6, 0.1)))
    for k in range(1, n):
        measured = np.linalg.inv(poses[k - 1]) @ poses[k] @ _transform(rng, 0.02, 0.1)
        graph.add(pose5_factor(X(k - 1), X(k), measured, robust if k % 2 else gaussian))
        graph.add(vertical_factor(X(k - 1), X(k), 0.0, gtsam.noiseModel.Isotropic.Sigma(1, 0.05)))
        if k % 3 == 0:
            graph.add(rotation_factor(X(k - 3), X(k), np.linalg.inv(poses[k - 3]) @ poses[k]))
        graph.add(
            gtsam.OrientedPlane3Factor(
                np.array([0.0, 0.0, 1.0, 1.5]),
                gtsam.noiseModel.Isotropic.Sigma(3, 0.01),
                X(k),
                L(0),
            )
        )
    flipped = g.make_transform(Rotation.from_rotvec([0.0, 0.0, 2.5]).as_matrix(), np.zeros(3))
    graph.add(pose5_factor(X(0), X(1), flipped))
    return graph, values


def _same_linear(a: gtsam.GaussianFactorGraph, b: gtsam.GaussianFactorGraph) -> bool:
    return a.size() == b.size() and all(
        list(a.at(i).keys()) == list(b.at(i).keys())
        and np.array_equal(a.at(i).augmentedJacobian(), b.at(i).augmentedJacobian())
        for i in range(a.size())
    )


def test_batched_errors_and_linearisation_equal_gtsams_bit_for_bit() -> None:
    rng = np.random.default_rng(3)
    graph, values = _graph(rng, 12)
    batched = BatchedResiduals(graph, values)
    assert batched.initial_error == graph.error(values)
    delta = gtsam.VectorValues()
    for key in values.keys():
        delta.insert(key, rng.normal(0.0, 0.05, 6 if key != L(0) else 3))
    for at in (values, values.retract(delta)):
        assert batched.error(at) == graph.error(at)
        assert _same_linear(batched.linearize(at), graph.linearize(at))


def test_the_callbacks_take_the_batched_rows(monkeypatch: object) -> None:
    """Every 5-DoF, rotation and vertical factor but the one beyond 90 degrees is served
    from the batch (the point of it): only that one computes its own residual; and
    nothing is left set after an evaluation."""
    graph, values = _graph(np.random.default_rng(4), 8)
    batched = BatchedResiduals(graph, values)
    own = []  # the factors that computed their own residual (not served)
    pose5_own, vertical_own = pose5._pose5, pose5._vertical_kernel

    def counting_pose5(*args: object) -> object:
        own.append("pose5")
        return pose5_own(*args)

    def counting_vertical(*args: object) -> object:
        own.append("vertical")
        return vertical_own(*args)

    monkeypatch.setattr(pose5, "_pose5", counting_pose5)  # type: ignore[attr-defined]
    monkeypatch.setattr(pose5, "_vertical_kernel", counting_vertical)  # type: ignore[attr-defined]
    batched.linearize(values)
    custom = [graph.at(i) for i in range(graph.size())]
    n_custom = sum(isinstance(f, gtsam.CustomFactor) for f in custom)
    assert own == ["pose5"]  # the one beyond 90 degrees (the kernel defers to gtsam)
    assert pose5._Precomputed.values is None
    own.clear()
    graph.error(values)  # outside the batch: every factor computes its own
    assert len(own) == n_custom


def test_a_shared_factor_takes_its_row_in_each_batch() -> None:
    """The same factors in two graphs at other rows (the loop start's graph shares the
    batch's factors): each batch writes its rows into the callbacks' cells before it
    evaluates, so either one, evaluated after the other, equals gtsam's own evaluation."""
    graph, values = _graph(np.random.default_rng(6), 8)
    other = gtsam.NonlinearFactorGraph()
    for i in reversed(range(graph.size())):  # the same factor objects, reversed
        other.add(graph.at(i))
    first, second = BatchedResiduals(graph, values), BatchedResiduals(other, values)
    for batched, fg in ((first, graph), (second, other), (first, graph), (second, other)):
        assert batched.error(values) == fg.error(values)
        assert _same_linear(batched.linearize(values), fg.linearize(values))


def test_other_values_fall_back_to_the_callbacks() -> None:
    """Values with other Pose3 keys than the first: each factor computes its own."""
    graph, values = _graph(np.random.default_rng(5), 6)
    batched = BatchedResiduals(graph, values)
    more = gtsam.Values(values)
    more.insert(X(99), gtsam.Pose3())
    assert batched.error(more) == graph.error(more)
    assert _same_linear(batched.linearize(more), graph.linearize(more))
