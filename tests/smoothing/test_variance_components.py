"""Variance component estimation against simulated graphs whose noise is k times its model."""

from __future__ import annotations

from dataclasses import replace

import gtsam
import numpy as np
import pytest
import scipy.sparse as sp

from planodom.config import SmoothingConfig
from planodom.geometry import Plane
from planodom.smoothing import smooth_batch
from planodom.smoothing.synthetic import make_sequence
from planodom.smoothing.variance_components import (
    EXACT_MAX_DIM,
    PROBES,
    estimate_components,
    leverages,
    scaled_linear,
)

X = gtsam.symbol_shorthand.X


def _noisy(T: gtsam.Pose3, sigmas: np.ndarray, rng: np.random.Generator) -> gtsam.Pose3:
    return T.retract(rng.normal(0.0, sigmas))


def _chain(n: int, k_odo: float, k_loop: float, seed: int = 0):
    """A Pose3 chain: odometry between neighbours (model sigmas ``s_o``, simulated with
    ``k_odo * s_o``) and 'loop' factors from every pose to the ones 3 and 7 ahead (model
    ``s_l``, simulated ``k_loop * s_l``); the graph solved, linearised at the estimate."""
    rng = np.random.default_rng(seed)
    truth = [gtsam.Pose3()]
    for _ in range(n - 1):
        truth.append(truth[-1].compose(gtsam.Pose3(gtsam.Rot3.Yaw(0.05), [1.0, 0.1, 0.0])))
    s_o = np.array([0.002, 0.002, 0.004, 0.02, 0.02, 0.01])
    s_l = np.array([0.004, 0.003, 0.002, 0.05, 0.03, 0.02])
    graph, labels = gtsam.NonlinearFactorGraph(), []
    graph.add(gtsam.PriorFactorPose3(X(0), truth[0], gtsam.noiseModel.Isotropic.Sigma(6, 1e-6)))
    labels.append(None)
    for i in range(n - 1):
        z = _noisy(truth[i].between(truth[i + 1]), k_odo * s_o, rng)
        graph.add(
            gtsam.BetweenFactorPose3(X(i), X(i + 1), z, gtsam.noiseModel.Diagonal.Sigmas(s_o))
        )
        labels.append("odo")
    for i, j in [(i, i + d) for d in (3, 7) for i in range(n - d)]:
        z = _noisy(truth[i].between(truth[j]), k_loop * s_l, rng)
        graph.add(gtsam.BetweenFactorPose3(X(i), X(j), z, gtsam.noiseModel.Diagonal.Sigmas(s_l)))
        labels.append("loop")
    values = gtsam.Values()
    for i, T in enumerate(truth):
        values.insert(X(i), T)
    values = gtsam.LevenbergMarquardtOptimizer(graph, values).optimize()
    return graph.linearize(values), {X(i): 6 for i in range(n)}, labels


def _spread(scale: float, redundancy: float) -> float:
    """Standard deviation of a variance factor estimated from ``redundancy`` dof."""
    return scale * np.sqrt(2.0 / redundancy)


@pytest.mark.parametrize("n", [120, 300])  # exact leverages, then Hutchinson's
def test_groups_recover_the_simulated_scales(n: int) -> None:
    linear, dims, labels = _chain(n, k_odo=3.0, k_loop=0.5)
    assert (6 * n > EXACT_MAX_DIM) == (n == 300)
    out = estimate_components(linear, dims, labels)
    assert out.converged
    for c, k in (("odo", 3.0), ("loop", 0.5)):
        assert abs(out.scales[c] - k**2) < 4 * _spread(k**2, out.redundancy[c]), (c, out.scales)
    # the redundancy numbers of every row sum to m - n (the prior's 6 rows have none)
    m = sum(out.rows.values()) + 6
    assert sum(out.redundancy.values()) == pytest.approx(m - 6 * n, rel=0.03)


def test_one_component_is_the_posterior_variance_factor() -> None:
    linear, dims, labels = _chain(120, k_odo=2.0, k_loop=2.0, seed=1)
    out = estimate_components(linear, dims, ["all" if c else None for c in labels])
    # one component, model scaled by k: the closed form v^T P v / (m - n) at once
    assert out.iterations <= 2
    assert abs(out.scales["all"] - 4.0) < 4 * _spread(4.0, out.redundancy["all"])
    A, b = linear.jacobian()
    v = A @ np.linalg.lstsq(A, b, rcond=None)[0] - b
    assert out.scales["all"] == pytest.approx(v @ v / (A.shape[0] - A.shape[1]), rel=1e-6)


def test_wrong_scales_are_found_wrong() -> None:
    """The same estimate on a graph simulated at the model (k = 1) gives 1, not 9."""
    linear, dims, labels = _chain(120, k_odo=1.0, k_loop=1.0, seed=2)
    out = estimate_components(linear, dims, labels)
    assert abs(out.scales["odo"] - 1.0) < 4 * _spread(1.0, out.redundancy["odo"])
    assert out.scales["odo"] < 2.0


def test_hutchinson_leverages_match_the_exact_ones() -> None:
    rng = np.random.default_rng(3)
    m, n = 6000, EXACT_MAX_DIM + 300
    A = sp.random(m, n, density=4.0 / n, random_state=4, format="csr") + sp.eye(m, n, format="csr")
    exact = np.einsum("ij,ji->i", A.toarray(), np.linalg.solve((A.T @ A).toarray(), A.toarray().T))
    estimated = leverages(A.tocsr(), seed=5)
    for rows in np.array_split(rng.permutation(m), 3):
        u = exact[rows].sum()
        assert abs(estimated[rows].sum() - u) < 4 * np.sqrt(2 * u / PROBES)


def test_scaled_linear_scales_the_information() -> None:
    linear, _, labels = _chain(20, 1.0, 1.0)
    scaled = scaled_linear(linear, labels, {"odo": 4.0, "loop": 1.0})
    for i in range(linear.size()):
        factor = 0.25 if labels[i] == "odo" else 1.0
        np.testing.assert_allclose(scaled.at(i).information(), factor * linear.at(i).information())


def _understated(k_planes: float, k_relatives: float, seed: int = 7):
    """A synthetic sequence whose declared covariances are the sampling ones divided by
    ``k**2`` (the noise is ``k`` times its model), planes and relative poses apart."""
    seq = make_sequence(
        60, seed=seed, sigma_rotation=1e-3, sigma_translation=0.01, sigma_normal=0.005,
        sigma_offset=0.01,
    )  # fmt: skip
    planes = [
        [Plane(p.normal, p.offset, covariance=p.covariance / k_planes**2) for p in epoch]
        for epoch in seq.planes
    ]
    relatives = [replace(r, covariance=r.covariance / k_relatives**2) for r in seq.relatives]
    return planes, relatives


# Gaussian, every relative pose a factor (the synthetic ones are sampled apart from the
# planes: no double counting), no deskewing error (the epochs are instants).
BATCH = SmoothingConfig(
    robust_kernel="none", between_factors="all", deskew_noise="none", loop_closure=False
)


def test_batch_groups_find_the_understated_group() -> None:
    planes, relatives = _understated(k_planes=3.0, k_relatives=1.0)
    config = BATCH.model_copy(update={"covariance_scale": "groups"})
    result = smooth_batch(planes, relatives, config)
    out = result.variance_components
    assert out is not None and out.converged
    # every plane factor (3 rows) and relative pose (5 rows) in its group, nothing else
    assert out.rows == {
        "plane": 3 * result.stats.plane_factors,
        "between": 5 * result.stats.between,
    }
    for group, k in (("plane", 3.0), ("between", 1.0)):
        spread = _spread(k**2, out.redundancy[group])
        assert abs(out.scales[group] - k**2) < 4 * spread, (group, out.scales, out.redundancy)


def test_batch_posterior_scales_the_covariances() -> None:
    planes, relatives = _understated(k_planes=2.0, k_relatives=2.0, seed=8)
    plain = smooth_batch(planes, relatives, BATCH)
    config = BATCH.model_copy(update={"covariance_scale": "posterior"})
    scaled = smooth_batch(planes, relatives, config)
    out = scaled.variance_components
    assert out is not None
    s = out.scales["measurements"]
    assert abs(s - 4.0) < 4 * _spread(4.0, out.redundancy["measurements"])
    np.testing.assert_allclose(scaled.poses, plain.poses)  # "keep": the same estimate
    assert plain.covariances is not None and scaled.covariances is not None
    # x, y, roll, pitch, yaw: observed by the measurements alone (z mostly by the
    # vertical pseudo-observations, which keep their weight)
    keep = np.ix_([0, 1, 2, 3, 4], [0, 1, 2, 3, 4])
    pairs = zip(scaled.covariances[1:], plain.covariances[1:], strict=True)
    ratio = [np.trace(a[keep]) / np.trace(b[keep]) for a, b in pairs]
    np.testing.assert_allclose(ratio, s, rtol=0.05)
