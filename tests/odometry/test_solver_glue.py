"""The solver's compiled glue against the numpy expressions it replaced, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.odometry.solver_glue import (
    all_finite,
    appended,
    kept_rows,
    near_rows,
    numpy_near_rows,
    numpy_pair_ids,
    numpy_remapped_pairs,
    pair_ids,
    remapped_pairs,
)


def _same(a: np.ndarray, b: np.ndarray) -> None:
    assert a.dtype == b.dtype and a.shape == b.shape
    assert a.tobytes() == b.tobytes()


@pytest.mark.parametrize("seed", range(5))
def test_pair_ids_numpy_values(seed: int) -> None:
    rng = np.random.default_rng(seed)
    full = rng.integers(0, 40, size=(int(rng.integers(0, 30)), 4)).astype(np.int64)
    for pairs in (full[:, :2], np.ascontiguousarray(full[:, 2:]), full[::2, 1:3]):
        _same(pair_ids(pairs), numpy_pair_ids(pairs))
    # ids tell pairs apart: two pairs share an id only when they are the same pair
    ids = pair_ids(full[:, :2])
    rows = {tuple(r) for r in full[:, :2].tolist()}
    assert len(set(ids.tolist())) == len(rows)


def test_pair_ids_other_dtypes_and_empty() -> None:
    for pairs in (np.array([[3, 1], [0, 7]], dtype=np.int32), np.zeros((0, 2), np.int64)):
        _same(pair_ids(pairs), numpy_pair_ids(pairs))


@pytest.mark.parametrize("seed", range(5))
def test_near_rows_numpy_verdicts_at_the_boundary(seed: int) -> None:
    rng = np.random.default_rng(seed)
    c = rng.normal(scale=rng.uniform(0.01, 3.0), size=(25, 2))
    c[3] = np.nan
    c[5, 1] = np.inf
    best = int(rng.integers(6, 25))
    dist = np.linalg.norm(c - c[best], axis=1)
    # tolerances at a row's own distance and one ulp either side, and generic ones
    tols = [0.0, 0.05, 1.0, np.inf]
    for k in (0, 1, 7, 11):
        tols += [dist[k], np.nextafter(dist[k], 0.0), np.nextafter(dist[k], np.inf)]
    for tol in tols:
        _same(near_rows(c, best, tol), numpy_near_rows(c, best, tol))


def test_near_rows_cases_the_kernel_does_not_take() -> None:
    c3 = np.arange(12.0).reshape(4, 3)
    _same(near_rows(c3, 1, 2.0), numpy_near_rows(c3, 1, 2.0))
    c32 = np.arange(8, dtype=np.float32).reshape(4, 2)
    _same(near_rows(c32, 0, 3.0), numpy_near_rows(c32, 0, 3.0))


def test_near_rows_known_values() -> None:
    c = np.array([[0.0, 0.0], [3.0, 4.0], [0.1, 0.0]])
    assert near_rows(c, 0, 5.0).tolist() == [True, True, True]
    assert near_rows(c, 0, 4.999).tolist() == [True, False, True]


def test_all_finite() -> None:
    a, b = np.ones((2, 4, 4)), np.zeros((2, 4, 4))
    assert all_finite(a, b)
    for bad in (np.nan, np.inf, -np.inf):
        c = b.copy()
        c[1, 3, 2] = bad
        assert not all_finite(a, c) and not all_finite(c, a)
    assert all_finite(a[:, ::2], b[::-1])  # strided views
    assert not all_finite(np.array([1, 2], np.float32), np.array([np.nan], np.float32))


def test_appended_values() -> None:
    txy = np.array([0.1 + 0.2, -3e-17])
    for z in (0.7, np.float64(-2.5), 0):
        _same(appended(txy, z), np.append(txy, z))
    _same(appended(np.array([1, 2]), 3.5), np.append(np.array([1, 2]), 3.5))


@pytest.mark.parametrize("seed", range(4))
def test_remapped_pairs_numpy_values(seed: int) -> None:
    rng = np.random.default_rng(seed)
    order_p, order_c = rng.permutation(9), rng.permutation(7)
    ij = np.column_stack([rng.integers(0, 9, 6), rng.integers(0, 7, 6)]).astype(np.intp)
    _same(remapped_pairs(ij, order_p, order_c), numpy_remapped_pairs(ij, order_p, order_c))
    # other dtypes go to numpy's expression
    ij32 = ij.astype(np.int32)
    _same(remapped_pairs(ij32, order_p, order_c), numpy_remapped_pairs(ij32, order_p, order_c))


@pytest.mark.parametrize("seed", range(4))
def test_kept_rows_boolean_indexing_values(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 12))
    mask = rng.random(n) < 0.6
    arrays = (
        rng.normal(size=(n, 2)), rng.integers(0, 9, (n, 4)).astype(np.intp),
        rng.normal(size=n), rng.normal(size=(n, 3, 3)), rng.normal(size=(n, 4))[:, ::2],
    )  # fmt: skip
    for got, a in zip(kept_rows(mask, *arrays), arrays, strict=True):
        _same(got, a[mask])
        assert got.flags.c_contiguous


def test_kept_rows_other_masks_as_numpy() -> None:
    a = np.arange(10.0).reshape(5, 2)
    _same(kept_rows(np.array([0, 2]), a)[0], a[np.array([0, 2])])  # an index array
    with pytest.raises(IndexError):
        kept_rows(np.array([True, False]), a)  # a mask of another length


def test_same_pairs_compares_bytes():
    from planodom.association import PairAssociations
    from planodom.odometry.solver_glue import same_pairs

    rng = np.random.default_rng(0)
    pp = rng.integers(0, 9, (5, 2)).astype(np.intp)
    cp = rng.integers(0, 9, (5, 2)).astype(np.intp)
    rot = rng.normal(size=(5, 3, 3))
    rot[0, 0, 1] = 0.0
    w = rng.random(5)
    a = PairAssociations(pp, cp, rot, w)
    assert same_pairs(a, PairAssociations(pp.copy(), cp.copy(), rot.copy(), w.copy()))
    signed = rot.copy()
    signed[0, 0, 1] = -0.0  # equal as numbers, not as bytes
    assert np.array_equal(signed, rot)
    assert not same_pairs(a, PairAssociations(pp, cp, signed, w))
    assert not same_pairs(a, PairAssociations(pp.astype(np.int32), cp, rot, w))
    assert not same_pairs(a, PairAssociations(pp[:4], cp[:4], rot[:4], w[:4]))
    assert not same_pairs(a, PairAssociations(cp, pp, rot, w))
    assert same_pairs(PairAssociations.empty(), PairAssociations.empty())


def test_same_float_tells_the_bits():
    """Equal numbers with other bits differ (a signed zero), NaN equals itself."""
    from planodom.odometry.solver_glue import same_float

    assert same_float(1.25, 1.25) and same_float(float("nan"), float("nan"))
    assert not same_float(0.0, -0.0) and not same_float(1.0, np.nextafter(1.0, 2.0))
