"""The batched landmark merge of update_map against merging one plane after the other."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.odometry.planemap.landmarks import PlaneMap, _merge_flat
from planodom.odometry.planemap.moments import Moments, merge_moments


def _random_map(rng: np.random.Generator, n: int) -> PlaneMap:
    sets = [rng.normal(size=(30, 3)) * [3, 2, 0.02] + rng.normal(size=3) * 5 for _ in range(n)]
    m = Moments.of_points(sets)
    M = PlaneMap()
    M.add(m, np.tile([0.0, 0.0, 1.0], (n, 1)), 0, np.arange(n))
    return M


def _one_by_one(M: PlaneMap, mw: Moments, js, assoc, tol2, new) -> None:
    """update_map's merge as it was written: a loop over the planes, in order."""
    for j in js:
        k = assoc[j]
        N, c, S = merge_moments(M.N[k], M.c[k], M.S[k], mw.N[j], mw.c[j], mw.S[j])
        if np.linalg.eigvalsh(S)[0] / N <= tol2:
            M.N[k], M.c[k], M.S[k] = N, c, S
            M.rows[k] += mw.rows[j]
            new[j] = False


@pytest.mark.parametrize("seed", range(6))
def test_batched_merge_equals_one_by_one_bit_for_bit(seed: int) -> None:
    rng = np.random.default_rng(seed)
    L, K = 6, 14
    scan = Moments.of_points(
        [rng.normal(size=(20, 3)) * [2, 2, rng.choice([0.01, 0.5])] for _ in range(K)]
    )
    assoc = rng.integers(-1, L, size=K)  # repeats: several planes into one landmark
    js = np.flatnonzero(assoc >= 0)
    tol2 = float(rng.choice([1e-4, 1e-2, 1.0]))  # none, some or all flat enough
    A = _random_map(np.random.default_rng(100 + seed), L)
    B = _random_map(np.random.default_rng(100 + seed), L)
    new_a, new_b = np.ones(K, dtype=bool), np.ones(K, dtype=bool)
    _merge_flat(A, scan, js, assoc, tol2, new_a)
    _one_by_one(B, scan, js, assoc, tol2, new_b)
    np.testing.assert_array_equal(new_a, new_b)
    for name in ("N", "c", "S", "rows"):
        assert getattr(A, name).tobytes() == getattr(B, name).tobytes(), name


def test_merge_of_nothing_changes_nothing() -> None:
    M = _random_map(np.random.default_rng(0), 3)
    before = M.S.copy()
    new = np.ones(2, dtype=bool)
    _merge_flat(M, Moments.of_points([np.zeros((3, 3))] * 2), np.zeros(0, np.intp),
                np.array([-1, -1]), 1.0, new)  # fmt: skip
    assert new.all() and M.S.tobytes() == before.tobytes()
