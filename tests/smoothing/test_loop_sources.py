"""Loop factors sharing their older epoch's error in the sandwich
(planodom.smoothing.loop_sources) against a dense computation of the sandwich from the
whitened Jacobian with that shared error written out."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from dense_sandwich import assert_sandwich_equals_dense, odometry_chain, whitened_jacobian

from planodom.config import PlanodomConfig, SmoothingConfig
from planodom.errors import ConfigError
from planodom.smoothing.graph import X
from planodom.smoothing.loop_sources import loop_source_maps
from planodom.smoothing.sandwich import sandwich_covariances

E = 7  # poses X0..X6; steps delta 1, loops X0-X5, X0-X6, X1-X6 (delta_max 3)
LOOPS = [(0, 5), (0, 6), (1, 6)]


def _graph(robust_loop: bool = False) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
    rng = np.random.default_rng(3)
    step = gtsam.Pose3(gtsam.Rot3.Yaw(0.3), gtsam.Point3(1.0, 0.2, 0.0))
    graph, values = odometry_chain(rng, step, E)
    for a, b in LOOPS:
        T = values.atPose3(X(a)).between(values.atPose3(X(b)))
        noise = gtsam.noiseModel.Diagonal.Sigmas(rng.uniform(0.02, 0.06, 6))
        if robust_loop and (a, b) == (1, 6):
            noise = gtsam.noiseModel.Robust.Create(
                gtsam.noiseModel.mEstimator.Cauchy.Create(1.0), noise
            )
        graph.add(gtsam.BetweenFactorPose3(X(a), X(b), T, noise))
    return graph, values


def test_maps_one_column_per_older_epoch() -> None:
    graph, _ = _graph(robust_loop=True)
    maps, Q = loop_source_maps(graph, E, delta_max=3)
    first = graph.size() - len(LOOPS)
    assert sorted(maps) == [first, first + 1]  # the steps and the robust loop left out
    assert maps[first][0] == maps[first + 1][0] == E  # both from X0: one column
    np.testing.assert_allclose(maps[first][1], np.sqrt(0.5) * np.eye(6))
    assert Q.shape == (1, 6, 6)


def test_sandwich_equals_the_dense_shared_error() -> None:
    graph, values = _graph()
    maps, Q = loop_source_maps(graph, E, delta_max=3)
    out, _ = sandwich_covariances(graph, values, E, {}, np.zeros((E, 6, 6)), False, 1e-3, (maps, Q))
    # dense: Cov = A^-1 J^T (I + G G^T) J A^-1, G: half of each loop factor's whitened
    # error from one unit error per older epoch (X0: two loops, X1: one)
    J, rows = whitened_jacobian(graph, values, E)
    older = {a: j for j, a in enumerate(sorted({a for a, _ in LOOPS}))}
    G = np.zeros((J.shape[0], 6 * len(older)))
    for i, (a, _) in enumerate(LOOPS, start=graph.size() - len(LOOPS)):
        G[rows[i] : rows[i + 1], 6 * older[a] : 6 * older[a] + 6] = np.sqrt(0.5) * np.eye(6)
    # and it is not the independent factors' (fitted) covariance
    assert_sandwich_equals_dense(out.covariances[:E], J, G, np.eye(G.shape[1]))


def test_option_default_and_validation() -> None:
    assert SmoothingConfig().sandwich_loop_sources == "independent"
    with pytest.raises(ConfigError, match="sandwich_loop_sources"):
        PlanodomConfig().updated({"smoothing.sandwich_loop_sources": "half"})
