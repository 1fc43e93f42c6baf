"""OCSC / WOCSC (paper eq. 3-4): against brute force, determinism, outliers, breakdown."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planodom.consensus import (
    apply_inverse_rotation,
    apply_negative_translation,
    consensus,
)
from planodom.geometry import rotation_frames


def brute_force(candidates, source, target, apply_one, weights, truncate=None):
    """Independent loop implementation of eq. 4: (errors (C,), best index)."""
    cap = np.inf if truncate is None else truncate**2
    errors = []
    for K in candidates:
        total = 0.0
        for x, y, w in zip(source, target, weights, strict=True):
            e = float(np.sum((apply_one(K, x) - y) ** 2))
            total += min(e, cap) * w
        errors.append(total)
    errors = np.array(errors)
    return errors, int(np.flatnonzero(errors == errors.min())[0])


@pytest.mark.parametrize("truncate", [None, 0.3])
def test_rotation_consensus_matches_brute_force(truncate):
    rng = np.random.default_rng(3)
    C, E = 17, 23
    R = Rotation.random(C, random_state=rng).as_matrix()
    src = rng.normal(size=(E, 3))
    tgt = rng.normal(size=(E, 3))
    w = rng.uniform(0.1, 1.0, E)
    res = consensus(R, src, tgt, apply_inverse_rotation, weights=w, truncate=truncate)
    errors, best = brute_force(R, src, tgt, lambda K, x: K.T @ x, w, truncate)
    np.testing.assert_allclose(res.errors, errors, rtol=1e-12)
    assert res.best_index == best
    np.testing.assert_array_equal(res.best_candidate, R[best])


def test_translation_consensus_matches_brute_force():
    rng = np.random.default_rng(4)
    T = rng.normal(size=(9, 2))
    src = rng.normal(size=(14, 2))
    tgt = rng.normal(size=(14, 2))
    res = consensus(T, src, tgt, apply_negative_translation)  # OCSC: unit weights
    errors, best = brute_force(T, src, tgt, lambda K, x: x - K, np.ones(14))
    np.testing.assert_allclose(res.errors, errors, rtol=1e-12)
    assert res.best_index == best


def test_plain_translation_consensus_is_candidate_nearest_weighted_mean():
    """sum_i w_i |T_j - T_i|^2 = W |T_j - mean_w|^2 + const: the winner is nearest the mean."""
    rng = np.random.default_rng(5)
    cands = rng.normal(size=(30, 2))
    w = rng.uniform(0.2, 1.0, 30)
    res = consensus(cands, cands, np.zeros((30, 2)), apply_negative_translation, weights=w)
    mean = w @ cands / w.sum()
    assert res.best_index == int(np.argmin(np.linalg.norm(cands - mean, axis=1)))


def test_ties_go_to_lowest_index_and_results_are_deterministic():
    cands = np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 0.0], [2.0, 0.0]])
    src = np.array([[0.0, 0.0], [0.0, 0.0]])
    res = consensus(cands, src, src, apply_negative_translation)
    assert res.best_index == 1
    again = consensus(cands, src, src, apply_negative_translation)
    np.testing.assert_array_equal(res.errors, again.errors)


def test_undefined_and_zero_weight_elements_are_ignored():
    cands = np.array([[0.0, 0.0], [1.0, 0.0]])
    src = np.array([[1.0, 0.0], [np.nan, np.nan], [5.0, 5.0]])
    tgt = np.array([[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    res = consensus(cands, src, tgt, apply_negative_translation, weights=[1.0, 1.0, 0.0],
                    inlier_tol=0.5)  # fmt: skip
    assert res.best_index == 1
    np.testing.assert_allclose(res.errors, [1.0, 0.0])
    assert res.inliers.tolist() == [True, False, False]
    assert res.n_inliers == 1 and res.best_error == 0.0


def test_bad_input_is_rejected():
    with pytest.raises(ValueError, match="at least one candidate"):
        consensus(np.zeros((0, 2)), np.zeros((1, 2)), np.zeros((1, 2)), apply_negative_translation)
    with pytest.raises(ValueError, match="weights"):
        consensus(np.zeros((1, 2)), np.zeros((2, 2)), np.zeros((2, 2)),
                  apply_negative_translation, weights=[1.0, -1.0])  # fmt: skip
    with pytest.raises(ValueError, match="targets"):
        consensus(np.zeros((1, 2)), np.zeros((2, 2)), np.zeros((3, 2)), apply_negative_translation)
    for bad in (np.nan, np.inf, -np.inf):  # the compiled check, as numpy's reductions
        with pytest.raises(ValueError, match="weights"):
            consensus(np.zeros((1, 2)), np.zeros((2, 2)), np.zeros((2, 2)),
                      apply_negative_translation, weights=[1.0, bad])  # fmt: skip
    with pytest.raises(ValueError, match="weights"):
        consensus(np.zeros((1, 2)), np.zeros((2, 2)), np.zeros((2, 2)),
                  apply_negative_translation, weights=[1.0, 1.0, 1.0])  # fmt: skip
    ok = consensus(np.zeros((1, 2)), np.zeros((2, 2)), np.zeros((2, 2)),
                   apply_negative_translation, weights=[0.0, 2.0])  # fmt: skip
    assert ok.best_index == 0 and ok.best_error == 0.0


def test_blocks_give_the_same_result_as_one_pass(monkeypatch):
    import planodom.consensus as mod

    rng = np.random.default_rng(6)
    R = Rotation.random(50, random_state=rng).as_matrix()
    src, tgt = rng.normal(size=(40, 3)), rng.normal(size=(40, 3))
    full = consensus(R, src, tgt, apply_inverse_rotation)
    monkeypatch.setattr(mod, "_BLOCK", 7)
    blocked = consensus(R, src, tgt, apply_inverse_rotation)
    np.testing.assert_array_equal(full.errors, blocked.errors)


# ----------------------------------------------------------------- outliers and breakdown


def rotation_trial(rng, n_elem, n_out, structured, truncate, noise=0.002):
    """Plane associations with ``n_out`` wrong ones; candidates from every element pair.

    Returns True when the winner comes from a pair of two correct associations.
    Structured outliers all agree with one wrong rotation (30 deg off): the worst case.
    """
    R = Rotation.random(random_state=rng).as_matrix()
    src = Rotation.random(n_elem, random_state=rng).apply([1.0, 0.0, 0.0])
    tgt = src @ R  # R^-1 n
    out = rng.permutation(n_elem)[:n_out]
    if structured:
        off = Rotation.from_rotvec(rng.normal(size=3) / np.sqrt(3) * np.radians(30)).as_matrix()
        tgt[out] = src[out] @ (R @ off)
    else:
        tgt[out] = Rotation.random(n_out, random_state=rng).apply([1.0, 0.0, 0.0])
    tgt += rng.normal(0.0, noise, tgt.shape)
    tgt /= np.linalg.norm(tgt, axis=1, keepdims=True)
    bad = np.zeros(n_elem, dtype=bool)
    bad[out] = True
    a, b = np.triu_indices(n_elem, 1)
    cands = rotation_frames(src[a], src[b]) @ np.swapaxes(rotation_frames(tgt[a], tgt[b]), 1, 2)
    res = consensus(cands, src, tgt, apply_inverse_rotation, truncate=truncate)
    return not (bad[a] | bad[b])[res.best_index]


def success_rate(n_out, structured, truncate, trials=60, seed=11):
    rng = np.random.default_rng(seed)
    return np.mean([rotation_trial(rng, 12, n_out, structured, truncate) for _ in range(trials)])


def test_wocsc_picks_the_right_rotation_with_few_wrong_associations():
    """Plain eq. 4 (the paper): 1 wrong association in 12 (8 %) never changes the winner."""
    assert success_rate(1, structured=False, truncate=None) == 1.0
    assert success_rate(1, structured=True, truncate=None) == 1.0


def test_measured_breakdown_of_plain_and_truncated_consensus():
    """Measured breakdown (12 elements; 300 trials per point gave, success rate by number
    of wrong associations 0..10):

    - plain, random wrong:     1.00 1.00 0.85 0.75 0.57 0.35 0.21 0.12 0.09 0.03 0.03
    - plain, conspiring:       1.00 1.00 0.88 0.57 0.23 0.04 0.01 0 ...
    - truncated, random:       1.00 ... 1.00 (up to 9 of 12) 0.83
    - truncated, conspiring:   1.00 1.00 0.99 0.99 0.98 0.97 0.47 0 ...

    Plain squared error (the paper) picks the candidate nearest the least-squares
    (Wahba) solution, so its breakdown fraction is about 1/6 (2 of 12). Truncated at a
    chord of 0.1 (5.7 deg) it holds to 5 of 12 (42 %) wrong associations that conspire on
    one rotation and breaks down at 50 %, as any consensus must.
    """
    assert success_rate(3, structured=True, truncate=None) < 0.8
    assert success_rate(4, structured=True, truncate=0.1) >= 0.95
    assert success_rate(8, structured=False, truncate=0.1) >= 0.95
    assert success_rate(7, structured=True, truncate=0.1) <= 0.05


def test_shortlist_beyond_the_budget_keeps_a_clear_winner():
    rng = np.random.default_rng(12)
    R_true = Rotation.random(random_state=rng).as_matrix()
    cands = Rotation.random(600, random_state=rng).as_matrix()
    cands[417] = R_true
    src = rng.normal(size=(300, 3))
    tgt = src @ R_true + rng.normal(0, 0.01, (300, 3))
    full = consensus(cands, src, tgt, apply_inverse_rotation, budget=None)
    short = consensus(cands, src, tgt, apply_inverse_rotation, budget=10_000, shortlist=16)
    assert full.best_index == short.best_index == 417
    assert np.isfinite(short.errors).sum() == 16
    assert short.errors[417] == full.errors[417]


@pytest.mark.parametrize("operator", ["rotation", "translation"])
def test_compiled_winner_errors_equal_the_generic_operators(operator):
    """The odometry's two operators run compiled (the candidates' totals and the winner's
    elements); the same operator wrapped (the generic numpy path) must give the same
    totals, errors and inliers, with groups, truncation, undefined and unweighted
    elements."""
    from scipy.spatial.transform import Rotation

    from planodom.consensus import apply_inverse_rotation, apply_negative_translation

    rng = np.random.default_rng(11)
    if operator == "rotation":
        apply, cands = apply_inverse_rotation, Rotation.random(7, random_state=3).as_matrix()
        src = rng.normal(size=(40, 3))
    else:
        apply, cands = apply_negative_translation, rng.normal(size=(7, 2))
        src = rng.normal(size=(40, 2))
    tgt = apply(cands[2:3], src)[0] + rng.normal(scale=0.05, size=src.shape)
    src[5] = np.nan  # an undefined element
    weights = rng.uniform(0.1, 1.0, 40)
    weights[7] = 0.0  # ignored
    groups = rng.integers(0, 30, 40)  # alternative associations, unsorted ids
    kw = dict(weights=weights, inlier_tol=0.08, groups=groups, truncate=1.5)
    fast = consensus(cands, src, tgt, apply, **kw)
    slow = consensus(cands, src, tgt, lambda c, x: apply(c, x), **kw)
    assert fast.best_index == slow.best_index == 2
    # the compiled totals add in element order, numpy's sum pairwise: rounding apart
    np.testing.assert_allclose(fast.errors, slow.errors, rtol=1e-13)
    np.testing.assert_array_equal(fast.element_errors, slow.element_errors)
    np.testing.assert_array_equal(fast.inliers, slow.inliers)
    assert np.isnan(fast.element_errors[5]) and not fast.inliers[5]
    assert 0 < fast.n_inliers < 39
