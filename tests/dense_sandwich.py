"""The sandwich covariance computed densely, an independent reference for the sparse one:
``Cov = A^-1 J^T (I + G S G^T) J A^-1`` with ``A = J^T J`` (J: the graph's whitened
Jacobian), ``G`` each factor's map from the shared errors and ``S`` their covariance."""

from __future__ import annotations

import gtsam
import numpy as np
from gtsam.symbol_shorthand import X


def whitened_jacobian(graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, n: int):  # noqa: ANN201
    """The whitened Jacobian (m, 6 n) over poses X(0..n-1) and each factor's first row
    (graph.size() + 1,), the last the row count."""
    ordering = gtsam.Ordering()
    for k in range(n):
        ordering.push_back(X(k))
    J = graph.linearize(values).jacobian(ordering)[0]
    rows = np.cumsum([0] + [graph.at(i).dim() for i in range(graph.size())])
    return J, rows


def assert_sandwich_equals_dense(
    covariances: list[np.ndarray], J: np.ndarray, G: np.ndarray, S: np.ndarray
) -> None:
    """Each pose's 6x6 block of the dense sandwich equals ``covariances[k]``, and the last
    is not the fitted covariance ``A^-1`` (the shared errors count)."""
    A_inv = np.linalg.inv(J.T @ J)
    C = A_inv @ J.T
    dense = A_inv + C @ G @ S @ G.T @ C.T
    for k, cov in enumerate(covariances):
        np.testing.assert_allclose(
            cov, dense[6 * k : 6 * k + 6, 6 * k : 6 * k + 6], rtol=1e-6, atol=1e-12
        )
    assert not np.allclose(covariances[-1], A_inv[-6:, -6:], rtol=1e-3)


def odometry_chain(
    rng: np.random.Generator, step: gtsam.Pose3, n: int
) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
    """Poses X(0..n-1) a constant ``step`` apart, each estimate perturbed by 0.01, a tight
    prior on X(0) and a between factor per step, its sigmas uniform in [0.01, 0.05]."""
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    pose = gtsam.Pose3()
    for k in range(n):
        values.insert(X(k), pose.retract(rng.normal(0.0, 0.01, 6)))
        pose = pose.compose(step)
    graph.add(
        gtsam.PriorFactorPose3(X(0), gtsam.Pose3(), gtsam.noiseModel.Isotropic.Sigma(6, 1e-3))
    )
    for k in range(1, n):
        noise = gtsam.noiseModel.Diagonal.Sigmas(rng.uniform(0.01, 0.05, 6))
        graph.add(gtsam.BetweenFactorPose3(X(k - 1), X(k), step, noise))
    return graph, values
