"""The factor's pattern of :mod:`planodom.smoothing.supernodal` against a dense Cholesky
factor's nonzeros."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from planodom.smoothing.supernodal import cholesky_pattern, m_matrix


def _cycle(n: int) -> sp.csc_matrix:
    """A loop of ``n`` scalar variables, each tied to its neighbours (a lap's chain and its
    closure): ``2.5 I`` less the cycle's adjacency, positive definite."""
    A = sp.diags([np.ones(n - 1), np.ones(n - 1)], [-1, 1], shape=(n, n), format="lil")
    A[0, n - 1] = A[n - 1, 0] = 1.0
    return sp.csc_matrix(2.5 * sp.identity(n) - A)


def _dense_pattern(S: np.ndarray, perm: np.ndarray) -> set[tuple[int, int]]:
    """The (row, column) nonzeros of the dense Cholesky factor of ``S`` permuted (variable
    i at ``perm[i]``); ``S``'s values generic, so no fill cancels."""
    order = np.argsort(perm)
    L = np.linalg.cholesky(S[np.ix_(order, order)])
    rows, cols = np.nonzero(L)
    return set(zip(rows.tolist(), cols.tolist(), strict=True))


@pytest.mark.parametrize("seed", range(4))
def test_pattern_is_the_dense_factors(seed: int) -> None:
    """On random sparse graphs with generic positive definite values, in the fill-reducing
    order of :func:`.sparse_sandwich._selected_inverse`: the pattern is exactly the dense
    factor's nonzeros, each column's rows sorted with the diagonal first."""
    rng = np.random.default_rng(seed)
    n = 80
    A = sp.random(n, n, density=0.04, random_state=rng, format="csc")
    A = A + A.T + sp.diags(np.arange(1.0, n), 1, shape=(n, n))  # a chain keeps it connected
    A = A + A.T
    S = (abs(A) + sp.identity(n) * (1.0 + abs(A).sum(axis=1).max())).tocsc()
    lu = spla.splu(m_matrix(S), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                   options={"SymmetricMode": True, "Equil": False})  # fmt: skip
    indices, indptr = cholesky_pattern(S, lu.perm_c)
    got = {(int(r), j) for j in range(n) for r in indices[indptr[j] : indptr[j + 1]]}
    assert got == _dense_pattern(S.toarray(), lu.perm_c)
    for j in range(n):
        col = indices[indptr[j] : indptr[j + 1]]
        assert col[0] == j and np.all(np.diff(col) > 0)


def test_pattern_keeps_the_fill_a_numeric_factor_underflows() -> None:
    """A loop of 3 000 variables (LAP14: lap 366 at 6 mm): the M-matrix's numeric LU (what
    the pattern came from before) underflows fill entries to exactly zero and drops them;
    the structural pattern keeps them, and equals the dense factor's nonzeros."""
    n = 3000
    S = _cycle(n)
    lu = spla.splu(m_matrix(S), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                   options={"SymmetricMode": True, "Equil": False})  # fmt: skip
    indices, indptr = cholesky_pattern(S, lu.perm_c)
    assert lu.L.nnz < len(indices)  # the numeric factor lost entries
    got = {(int(r), j) for j in range(n) for r in indices[indptr[j] : indptr[j + 1]]}
    assert got == _dense_pattern(S.toarray(), lu.perm_c)
