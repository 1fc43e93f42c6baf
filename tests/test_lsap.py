"""The compiled assignment gives scipy's assignment: scipy itself is the oracle.

Every case is solved by ``scipy.optimize.linear_sum_assignment`` and by the port
(:mod:`planodom.lsap`); rows and columns must be equal (values and dtype), and scipy's
errors the same errors. Integer matrices of a few values are full of ties, where any
other order of operations or tie rule picks another optimal assignment and fails here.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import linear_sum_assignment as scipy_lsap

from planodom.lsap import INFEASIBLE, INVALID, SOLVED, linear_sum_assignment, lsap_kernel


def _outcome(solve, cost):
    """(rows, cols) or the ValueError's message."""
    try:
        rows, cols = solve(cost)
    except ValueError as err:
        return str(err)
    return rows, cols


def _assert_same(cost: np.ndarray) -> None:
    want, got = _outcome(scipy_lsap, cost), _outcome(linear_sum_assignment, cost)
    if isinstance(want, str):
        assert got == want
        return
    assert not isinstance(got, str), got
    for w, g in zip(want, got, strict=True):
        assert g.dtype == w.dtype and g.shape == w.shape
        np.testing.assert_array_equal(g, w)


def _case(rng: np.random.Generator, kind: str, nr: int, nc: int) -> np.ndarray:
    if kind == "uniform":
        return rng.random((nr, nc))
    if kind == "ties":  # integers 0..2: many optimal assignments
        return rng.integers(0, 3, (nr, nc)).astype(np.float64)
    if kind == "constant":
        return np.full((nr, nc), 0.5)
    if kind == "inf":  # forbidden entries, some matrices infeasible
        cost = rng.integers(0, 4, (nr, nc)).astype(np.float64)
        cost[rng.random((nr, nc)) < 0.4] = np.inf
        return cost
    if kind == "sda":  # SDA's costs: gated ones in [0, 2], the others 1e6
        return np.where(rng.random((nr, nc)) < 0.5, 1e6, 2.0 * rng.random((nr, nc)))
    # "scales": wide exponents, where additions round
    return rng.random((nr, nc)) * 10.0 ** rng.integers(-8, 9, (nr, nc))


KINDS = ("uniform", "ties", "constant", "inf", "sda", "scales")


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("shape", ["square", "wide", "tall"])
def test_the_port_is_scipys_assignment(kind: str, shape: str) -> None:
    rng = np.random.default_rng(KINDS.index(kind) * 7 + len(shape))
    for _ in range(300):
        n = int(rng.integers(1, 9))
        m = n + int(rng.integers(1, 5)) if shape != "square" else n
        nr, nc = (n, m) if shape != "tall" else (m, n)
        _assert_same(_case(rng, kind, nr, nc))


@pytest.mark.parametrize("shape", [(0, 0), (0, 4), (3, 0)])
def test_an_empty_matrix_has_no_pairs(shape: tuple[int, int]) -> None:
    _assert_same(np.zeros(shape))
    status, rows, cols = lsap_kernel(np.zeros(shape))
    assert status == SOLVED and len(rows) == len(cols) == 0


@pytest.mark.parametrize("bad", [np.nan, -np.inf])
def test_invalid_entries_raise_scipys_error(bad: float) -> None:
    cost = np.arange(12.0).reshape(3, 4)
    cost[1, 2] = bad
    _assert_same(cost)
    _assert_same(cost.T.copy())
    assert lsap_kernel(cost)[0] == INVALID


def test_an_infeasible_matrix_raises_scipys_error() -> None:
    cost = np.array([[1.0, np.inf, np.inf], [2.0, np.inf, np.inf], [0.0, 1.0, 2.0]])
    _assert_same(cost)
    _assert_same(cost.T.copy())
    assert lsap_kernel(cost)[0] == INFEASIBLE
    _assert_same(np.full((2, 3), np.inf))


def test_other_inputs_are_converted_as_scipy_converts_them() -> None:
    rng = np.random.default_rng(5)
    ints = rng.integers(0, 5, (4, 6))
    _assert_same(ints)  # integers -> float64
    _assert_same(rng.random((6, 8))[::2, ::2])  # a strided view
    _assert_same(np.asfortranarray(rng.random((5, 3))))
    _assert_same(rng.random(4))  # not 2-D: scipy's message


def test_a_known_assignment() -> None:
    """scipy's docstring example, by hand: total 5 with columns (1, 0, 2)."""
    rows, cols = linear_sum_assignment(np.array([[4, 1, 3], [2, 0, 5], [3, 2, 2]]))
    np.testing.assert_array_equal(rows, [0, 1, 2])
    np.testing.assert_array_equal(cols, [1, 0, 2])
