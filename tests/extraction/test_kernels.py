"""The shared compiled helpers of the extraction against numpy."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from planodom.extraction.kernels import components, median_nonnegative


def _samples(kind: str, n: int, rng: np.random.Generator) -> np.ndarray:
    if kind == "noise":
        return np.abs(rng.normal(size=n)) * 1e-3
    if kind == "ties":
        return rng.integers(0, 5, n).astype(np.float64)
    if kind == "zeros":
        return np.zeros(n)
    if kind == "heavy":
        return np.abs(rng.standard_cauchy(n))
    return np.concatenate([np.full(n // 2, 0.5), rng.uniform(0, 1, n - n // 2)])


@pytest.mark.parametrize("kind", ["noise", "ties", "zeros", "heavy", "half-repeated"])
def test_median_nonnegative_is_numpys_median_exactly(kind):
    rng = np.random.default_rng(len(kind))
    for n in [1, 2, 3, 4, 31, 32, 33, 34, 100, 101, 4096, 8603, 8604]:
        a = _samples(kind, n, rng)
        padded = np.concatenate([a, rng.normal(size=5)])  # values beyond n are ignored
        assert median_nonnegative(padded, n) == np.median(a), (kind, n)


def test_median_of_tiny_values_and_subnormals():
    a = np.array([5e-324, 0.0, 1e-310, 3e-308, 2.5e-320, 1e300])
    for n in range(1, len(a) + 1):
        assert median_nonnegative(a, n) == np.median(a[:n])


def test_group_refits_are_the_moments_of_their_inliers():
    """The compiled group refit (its centroid summed while selecting the inliers) against
    numpy on each group's final inliers: centroid, scatter eigenvalues and normal, the
    inliers within k_sigma robust scales of that plane."""
    from planodom.config import ExtractionConfig
    from planodom.extraction.rig2d.groupfit import fit_groups
    from planodom.extraction.rig2d.grouping import GroupingParams
    from planodom.extraction.rig2d.groups import group_segments
    from planodom.extraction.rig2d.segments import split_scan_lines

    from .synth_scans import default_scene, scan_rig

    cfg = ExtractionConfig()
    scan = scan_rig(default_scene(), sigma=0.01)
    segs, sigma = split_scan_lines(scan.points, scan.ring, scan.t, cfg)
    params = GroupingParams(
        tol_m=0.05, sigma_m=float(sigma), sin_min_cross=float(np.sin(np.radians(20.0))),
        max_seed_err_rad=float(np.radians(5.0)), min_points=30.0, max_rms_m=0.05,
        min_trace_points=5, seed_floor_m=0.02, gap_m=1.0, gap_ratio=0.2, max_span_s=np.inf,
        max_seed_normal_err_rad=float(np.radians(10.0)),
    )  # fmt: skip
    groups, _ = group_segments(segs, params, cfg.trace_parallel_deg, cfg.trace_step_m)
    assert len(groups) >= 2
    fits = fit_groups(segs, groups, cfg.inlier_sigma_factor, None)
    for g in range(len(groups)):
        pts = segs.points[fits.inliers[fits.bounds[g] : fits.bounds[g + 1]]]
        assert len(pts) == fits.count[g] >= 3
        c = pts.mean(axis=0)
        q = pts - c
        vals, vecs = np.linalg.eigh(q.T @ q)
        np.testing.assert_allclose(fits.centroid[g], c, rtol=0, atol=1e-12)
        np.testing.assert_allclose(fits.evals[g], vals, rtol=1e-9, atol=1e-12)
        assert abs(abs(fits.evecs[g][:, 0] @ vecs[:, 0]) - 1.0) < 1e-9


@pytest.mark.parametrize("n", [1, 2, 5, 40, 300])
def test_components_are_scipys_labels(n):
    """The number of components and every node's label as scipy numbers them (the order
    of each component's smallest node), on random sparse and dense edge lists with
    repeated edges, self-loops, isolated nodes and edges given in either direction."""
    rng = np.random.default_rng(n)
    for m in [0, 1, n // 2, n, 3 * n]:
        a = rng.integers(0, n, m).astype(np.int64)
        b = rng.integers(0, n, m).astype(np.int64)
        if m > 2:
            a[-1], b[-1] = b[0], a[0]  # an edge repeated the other way round
        graph = coo_matrix((np.ones(m), (a, b)), shape=(n, n))
        want_m, want = connected_components(graph, directed=False)
        got_m, got = components(a, b, n)
        assert got_m == want_m
        np.testing.assert_array_equal(got, want)


def test_components_number_by_smallest_node_not_by_edges():
    """A chain given from its largest node down, and a component whose smallest node
    comes after another component's nodes: the labels follow the smallest nodes."""
    a = np.array([5, 4, 1], dtype=np.int64)
    b = np.array([4, 3, 6], dtype=np.int64)
    m, label = components(a, b, 7)
    assert m == 4
    np.testing.assert_array_equal(label, [0, 1, 2, 3, 3, 3, 1])
