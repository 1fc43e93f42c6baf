"""Consistency of the smoothing's covariances: measurements used once, gauge-free and
inlier-weighted marginals, and NEES of smoothed poses on simulated runs."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import chi2

from planodom.config import PlanodomConfig, SmoothingConfig
from planodom.experiments.consistency import (
    chi2_interval,
    consistency_tables,
    simulate_inputs,
    smoothed_nees,
)
from planodom.smoothing import smooth_batch
from planodom.smoothing.synthetic import make_sequence

NOISE = dict(sigma_rotation=1e-3, sigma_translation=0.01, sigma_normal=0.005, sigma_offset=0.01)


def with_sources(relatives):
    """The relative poses as if computed from (all) their associated planes."""
    return [replace(r, sources=r.associations) for r in relatives]


def test_a_relative_pose_of_tracked_planes_is_not_a_second_factor() -> None:
    seq = make_sequence(20, seed=2, **NOISE)
    derived = with_sources(seq.relatives)
    untracked = smooth_batch(seq.planes, derived, SmoothingConfig())
    assert untracked.stats.between == 0
    assert untracked.stats.between_left_out == len(seq.relatives)
    assert untracked.stats.plane_factors > 0
    both = smooth_batch(seq.planes, derived, SmoothingConfig(between_factors="all"))
    assert both.stats.between == len(seq.relatives) and both.stats.between_left_out == 0
    # Independent relative poses (no sources) always stay.
    independent = smooth_batch(seq.planes, seq.relatives, SmoothingConfig())
    assert independent.stats.between == len(seq.relatives)
    # A source plane without a plane factor keeps the relative pose.
    some = [replace(r, sources=np.array([[999, 999]])) for r in seq.relatives]
    assert smooth_batch(seq.planes, some, SmoothingConfig()).stats.between == len(some)


def test_covariances_are_relative_to_the_first_pose() -> None:
    """Gauge-free: the first pose's prior sigma no longer leaks into every covariance."""
    seq = make_sequence(25, seed=4, **NOISE)
    out = {}
    for relative in (True, False):
        for prior in (1e-4, 1e-2):
            # The gauge alone: epoch 0's deskewed frame would add its own (real) uncertainty.
            cfg = SmoothingConfig(
                covariances_relative_to_first=relative, prior_sigma=prior, deskew_noise="none"
            )
            out[relative, prior] = smooth_batch(seq.planes, seq.relatives, cfg).covariances
    sig = {key: np.sqrt(np.diagonal(c, axis1=1, axis2=2))[1:] for key, c in out.items()}
    np.testing.assert_allclose(sig[True, 1e-4], sig[True, 1e-2], rtol=2e-3)
    # 1e-2 rad and m of gauge in every rotation and horizontal position (z is loose anyway)
    assert np.all(sig[False, 1e-2][:, :5] > 1.5 * sig[True, 1e-2][:, :5])
    assert np.all(sig[True, 1e-4] <= sig[False, 1e-4] * (1 + 1e-6))


def test_inlier_factors_count_with_full_weight_in_the_covariances() -> None:
    """On clean data a robust graph's covariances are the Gaussian graph's, unless the
    kernel's weights are kept (then they are inflated)."""
    seq = make_sequence(25, seed=5, **NOISE)
    # The kernel's effect alone: the deskew frames' factors carry no kernel weights.
    base = dict(plane_factor="anchored", deskew_noise="none")
    gauss = smooth_batch(seq.planes, seq.relatives, SmoothingConfig(robust_kernel="none", **base))
    robust = smooth_batch(seq.planes, seq.relatives, SmoothingConfig(**base))
    weighted = smooth_batch(
        seq.planes, seq.relatives, SmoothingConfig(covariance_inlier_quantile=None, **base)
    )

    def trace(res):
        return np.trace(res.covariances[1:], axis1=1, axis2=2)

    ratio = trace(robust) / trace(gauss)
    assert np.all(ratio > 0.9) and np.all(ratio < 1.15), ratio
    assert np.median(trace(weighted) / trace(gauss)) > 1.2


def test_chi2_interval_of_an_average() -> None:
    lo, hi = chi2_interval(5, 1)
    assert (lo, hi) == pytest.approx(tuple(chi2.ppf([0.025, 0.975], 5)))
    lo, hi = chi2_interval(5, 1000)
    assert 4.5 < lo < 5 < hi < 5.5


def assert_consistent(values: list[np.ndarray], dof: int = 5) -> None:
    """Average NEES of whole runs inside the 99 % interval of ``len(values)`` independent
    chi2(dof) values: as if each run's epochs were one sample (their errors are strongly
    correlated), the most generous bound a consistent smoother must meet."""
    runs = len(values)
    mean = float(np.mean(np.concatenate(values)))
    lo, hi = chi2.ppf([0.005, 0.995], dof * runs) / runs
    assert lo < mean < hi, (mean, lo, hi, [float(np.mean(v)) for v in values])


def test_smoothed_poses_are_consistent_on_a_simulated_run() -> None:
    """Urban canyon, 6 mm range noise. Before the consistency fixes (between factors
    beside their planes' factors, plane covariances divided by the confidence and floored
    at 1 mm, the gauge prior in every marginal, Huber weights in the marginals) the
    average was 0.4 (covariances ten times too large)."""
    config = PlanodomConfig()
    values = []
    for seed in (1, 2):
        inp = simulate_inputs("urban-canyon", 0.006, config, seed, n_epochs=30)
        result = smooth_batch(inp.planes, inp.relatives, config.smoothing)
        values.append(smoothed_nees(result, inp.gt_poses))
    assert_consistent(values)


@pytest.mark.slow
def test_smoothed_poses_are_consistent_on_both_scenes() -> None:
    """Both scenes at 6 mm and 2 cm, three runs each (about a minute)."""
    config = PlanodomConfig()
    inputs = [
        simulate_inputs(scene, noise, config, seed, n_epochs=60)
        for scene in ("paper-loop", "urban-canyon")
        for noise in (0.006, 0.02)
        for seed in (1, 2, 3)
    ]
    for scene in ("paper-loop", "urban-canyon"):
        for noise in (0.006, 0.02):
            runs = [i for i in inputs if i.scene == scene and i.noise == noise]
            values = [
                smoothed_nees(smooth_batch(i.planes, i.relatives, config.smoothing), i.gt_poses)
                for i in runs
            ]
            assert_consistent(values)
    tables = consistency_tables(inputs[:3], config.smoothing, ("graph", "all"))
    assert [r["variant"] for r in tables["smoothed"]] == ["graph", "all"]
    assert tables["odometry"] and tables["planes"][0]["n"] > 0
