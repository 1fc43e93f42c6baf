"""Pose marginals by the Schur complement (planodom.smoothing.marginals) against gtsam."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from planodom.config import SmoothingConfig
from planodom.smoothing.batch import group_by_epoch
from planodom.smoothing.graph import GraphBuilder, X
from planodom.smoothing.marginals import pose_marginals, schur_preferred
from planodom.smoothing.synthetic import make_sequence

NOISE = dict(sigma_rotation=1e-3, sigma_translation=0.01, sigma_normal=0.005, sigma_offset=0.01)


@pytest.mark.parametrize("plane_factor", ["anchored", "global"])
def test_schur_marginals_are_gtsams(plane_factor: str) -> None:
    seq = make_sequence(25, seed=3, **NOISE)
    config = SmoothingConfig(plane_factor=plane_factor, robust_planes=False)
    builder = GraphBuilder(config)
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    by_epoch = group_by_epoch(seq.relatives, len(seq.planes))
    for k, planes in enumerate(seq.planes):
        update = builder.add_epoch(planes, by_epoch[k])
        graph.push_back(update.factors)
        values.insert(update.values)
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
