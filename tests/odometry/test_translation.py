"""The translation elements of plane pairs against the batched reference points of
:func:`planodom.geometry.horizontal_reference_points` (numpy, an independent path)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planodom.geometry import horizontal_reference_points
from planodom.odometry.translation import height_elements, translation_elements
from planodom.planes import PlaneSet


def _plane_set(rng: np.random.Generator, k: int) -> PlaneSet:
    n = rng.normal(size=(k, 3))
    n[:, 2] *= 0.3  # mostly walls, some flat enough to give no reference point
    n[0] = [0.0, 0.0, 1.0]  # a ground plane: its pairs cut horizontally
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return PlaneSet(
        n, rng.normal(size=k) * 5, rng.uniform(0.1, 1, k), rng.normal(size=(k, 3)),
        np.ones(k), np.zeros((k, 4, 4)),
    )  # fmt: skip


def _expected(prev, curr, R, pp, cp, min_vert, min_angle):
    i1, i2, j1, j2 = pp[:, 0], pp[:, 1], cp[:, 0], cp[:, 1]
    n1, n2 = curr.normals[j1] @ R.T, curr.normals[j2] @ R.T
    ref_p = horizontal_reference_points(
        prev.normals[i1], prev.offsets[i1], prev.normals[i2], prev.offsets[i2], min_vert
    )
    ref_c = horizontal_reference_points(n1, curr.offsets[j1], n2, curr.offsets[j2], min_vert)
    slope = horizontal_reference_points(n1, -n1[:, 2], n2, -n2[:, 2], min_vert)
    cos_p = np.sum(prev.normals[i1] * prev.normals[i2], axis=1)
    cos_c = np.sum(curr.normals[j1] * curr.normals[j2], axis=1)
    ok = np.isfinite(ref_p).all(axis=1) & np.isfinite(ref_c).all(axis=1)
    ok &= np.abs(cos_p) <= np.cos(min_angle)
    w = prev.weights[i1] * prev.weights[i2] * curr.weights[j1] * curr.weights[j2]
    w = w * (1 - cos_p**2) * (1 - cos_c**2)
    return np.column_stack([pp, cp])[ok], ref_p[ok], ref_c[ok], slope[ok], w[ok]


@pytest.mark.parametrize("seed", range(5))
def test_translation_elements_match_the_batched_reference_points(seed):
    rng = np.random.default_rng(seed)
    prev, curr = _plane_set(rng, 7), _plane_set(rng, 7)
    R = Rotation.from_rotvec(rng.normal(size=3) * 0.1).as_matrix()
    pp, cp = rng.integers(0, 7, (60, 2)), rng.integers(0, 7, (60, 2))
    got = translation_elements(prev, curr, R, pp, cp, 0.2, np.radians(10.0))
    pairs, ref_p, ref_c, slope, w = _expected(prev, curr, R, pp, cp, 0.2, np.radians(10.0))
    assert 0 < len(got) < 60  # some pairs parallel, flat or with the ground: dropped
    np.testing.assert_array_equal(got.pairs, pairs)
    for a, b in ((got.ref_prev, ref_p), (got.ref_curr0, ref_c), (got.slope, slope)):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(got.weights, w, rtol=1e-12)


def test_translation_candidates_recover_a_horizontal_shift():
    """Walls seen from two poses a pure shift (tx, ty) apart: every element gives it."""
    rng = np.random.default_rng(9)
    n = rng.normal(size=(5, 3))
    n[:, 2] = 0.0
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    d = rng.uniform(2, 8, 5)
    t = np.array([0.4, -0.3, 0.0])
    prev = PlaneSet(n, d, np.ones(5), np.zeros((5, 3)), np.ones(5), np.zeros((5, 4, 4)))
    curr = PlaneSet(n, d + n @ t, np.ones(5), np.zeros((5, 3)), np.ones(5), np.zeros((5, 4, 4)))
    a, b = np.triu_indices(5, 1)
    pairs = np.column_stack([a, b])
    el = translation_elements(prev, curr, np.eye(3), pairs, pairs, 0.2, np.radians(5.0))
    assert len(el) == 10
    np.testing.assert_allclose(el.candidates(0.0), np.tile(t[:2], (10, 1)), atol=1e-12)


def _former_heights(prev, curr, ij, max_tilt):
    """``height_elements``' numpy expression before SPEED2D8 (the oracle)."""
    n = prev.normals[ij[:, 0]]
    keep = n[:, 2] >= np.cos(max_tilt)
    ij, n = ij[keep], n[keep]
    b = (curr.offsets[ij[:, 1]] - prev.offsets[ij[:, 0]]) / n[:, 2]
    w = prev.weights[ij[:, 0]] * curr.weights[ij[:, 1]]
    return b, n[:, :2] / n[:, 2:3], w, ij


@pytest.mark.parametrize("seed", range(5))
def test_height_elements_equal_the_former_expression_bit_for_bit(seed):
    """Ground-like planes among tilted ones, none, all; the compiled values are numpy's."""
    rng = np.random.default_rng(40 + seed)
    prev, curr = _plane_set(rng, 8), _plane_set(rng, 8)
    prev.normals[1:4] = Rotation.from_rotvec(rng.normal(size=(3, 3)) * 0.2).apply([0, 0, 1.0])
    ij = np.column_stack([rng.permutation(8), rng.permutation(8)]).astype(np.intp)
    for tilt in (np.radians(5.0), np.radians(20.0), 0.0, np.pi):
        for rows in (ij, ij[:0], ij[:3]):
            got = height_elements(prev, curr, rows, tilt)
            b, m, w, kept = _former_heights(prev, curr, rows, tilt)
            for a, e in ((got.b, b), (got.m, m), (got.weights, w), (got.ij, kept)):
                assert a.dtype == e.dtype and a.shape == e.shape
                assert a.tobytes() == e.tobytes()
    assert 0 < len(height_elements(prev, curr, ij, np.radians(20.0))) < 8
