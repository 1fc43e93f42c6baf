"""The rectangular linear sum assignment, compiled: scipy's ``linear_sum_assignment``
ported operation for operation, so that a compiled kernel can assign.

The brief asks for scipy's assignment; scipy's is a C++ function behind a Python call, so
a numba kernel cannot call it: SDA (:func:`planodom.association.strict_association`) ran
its costs, scipy's assignment and its gate in three calls, and the refinement between its
kernels. This is the same algorithm as scipy's ``rectangular_lsap.cpp`` (scipy 1.6 and
later: the shortest augmenting path of DF Crouse, "On implementing 2D rectangular
assignment algorithms", IEEE TAES 52(4), 2016, pp. 1685-1686), with its order of
operations, so that it returns scipy's assignment to the bit, ties included:

- a tall matrix (more rows than columns) is solved transposed, and its pairs sorted by row;
- the columns left are scanned from a list filled in reverse and shrunk by moving its last
  entry into the chosen slot (a constant matrix gives the identity);
- among columns of equal lowest path cost the last one scanned wins unless an earlier one
  is free (a new sink): ``cost < lowest or (cost == lowest and free)``;
- a path's reduced cost is ``((minVal + cost) - u[i]) - v[j]``, in that order (additions
  only: no product a compiler could fuse).

Outcomes as scipy's: an empty matrix gives empty pairs; NaN or -inf entries are invalid
(:data:`INVALID`), a matrix with no finite complete assignment infeasible
(:data:`INFEASIBLE`); :func:`linear_sum_assignment` raises scipy's ``ValueError`` for
them. Tested against scipy itself (``tests/test_lsap.py``).
"""

from __future__ import annotations

import numba
import numpy as np

#: :func:`lsap_kernel`'s status codes (scipy's ``RECTANGULAR_LSAP_*``).
SOLVED, INFEASIBLE, INVALID = 0, -1, -2


def linear_sum_assignment(cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``scipy.optimize.linear_sum_assignment(cost)`` (minimisation), by the compiled
    port: (K,) int64 rows, sorted, and (K,) int64 columns, K the smaller dimension;
    ``ValueError`` with scipy's message for an invalid or infeasible matrix or one that
    is not 2-D."""
    c = np.ascontiguousarray(cost, dtype=np.float64)
    if c.ndim != 2:
        raise ValueError(f"expected a matrix (2-D array), got a {c.ndim} array")
    status, rows, cols = lsap_kernel(c)
    if status == INFEASIBLE:
        raise ValueError("cost matrix is infeasible")
    if status == INVALID:
        raise ValueError("matrix contains invalid numeric entries")
    return rows, cols


@numba.njit(cache=True)
def lsap_kernel(cost):  # pragma: no cover - compiled
    """The assignment of ``cost`` (nr, nc) float64: (status, rows (K,), cols (K,)) int64,
    K = min(nr, nc), rows sorted; the status :data:`SOLVED`, :data:`INFEASIBLE` or
    :data:`INVALID` (then the pairs are empty). scipy's ``solve`` step by step (module
    docstring)."""
    nr0, nc0 = cost.shape
    if nr0 == 0 or nc0 == 0:
        return SOLVED, np.empty(0, np.int64), np.empty(0, np.int64)
    transpose = nc0 < nr0
    nr, nc = (nc0, nr0) if transpose else (nr0, nc0)
    c = np.empty(nr * nc)
    for i in range(nr0):
        for j in range(nc0):
            if transpose:
                c[j * nr0 + i] = cost[i, j]
            else:
                c[i * nc0 + j] = cost[i, j]
    for k in range(nr * nc):
        if c[k] != c[k] or c[k] == -np.inf:
            return INVALID, np.empty(0, np.int64), np.empty(0, np.int64)
    u = np.zeros(nr)
    v = np.zeros(nc)
    spc = np.empty(nc)
    path = np.full(nc, -1, np.int64)
    col4row = np.full(nr, -1, np.int64)
    row4col = np.full(nc, -1, np.int64)
    SR = np.zeros(nr, np.bool_)
    SC = np.zeros(nc, np.bool_)
    remaining = np.empty(nc, np.int64)
    for cur in range(nr):
        sink, min_val = _augmenting_path(nc, c, u, v, path, row4col, spc, cur, SR, SC, remaining)
        if sink < 0:
            return INFEASIBLE, np.empty(0, np.int64), np.empty(0, np.int64)
        # update the dual variables
        u[cur] += min_val
        for i in range(nr):
            if SR[i] and i != cur:
                u[i] += min_val - spc[col4row[i]]
        for j in range(nc):
            if SC[j]:
                v[j] -= min_val - spc[j]
        # augment the previous solution
        j = sink
        while True:
            i = path[j]
            row4col[j] = i
            col4row[i], j = j, col4row[i]
            if i == cur:
                break
    rows = np.empty(nr, np.int64)
    cols = np.empty(nr, np.int64)
    if transpose:
        # scipy's argsort of col4row (its values are distinct: any sort gives this order)
        order = np.argsort(col4row)
        for k in range(nr):
            rows[k] = col4row[order[k]]
            cols[k] = order[k]
    else:
        for k in range(nr):
            rows[k] = k
            cols[k] = col4row[k]
    return SOLVED, rows, cols


@numba.njit(cache=True)
def _augmenting_path(nc, c, u, v, path, row4col, spc, i, SR, SC, remaining):  # pragma: no cover
    """scipy's ``augmenting_path`` from row ``i``: (sink column, its path cost), sink -1
    when no finite path is left (infeasible)."""
    min_val = 0.0
    num_remaining = nc
    for it in range(nc):
        # filled in reverse: a constant cost matrix gives the identity (scipy #11602)
        remaining[it] = nc - it - 1
    SR[:] = False
    SC[:] = False
    spc[:] = np.inf
    sink = -1
    while sink == -1:
        index = -1
        lowest = np.inf
        SR[i] = True
        for it in range(num_remaining):
            j = remaining[it]
            r = min_val + c[i * nc + j] - u[i] - v[j]
            if r < spc[j]:
                path[j] = i
                spc[j] = r
            # among equal lowest costs, one that gives a new sink (a free column)
            if spc[j] < lowest or (spc[j] == lowest and row4col[j] == -1):
                lowest = spc[j]
                index = it
        min_val = lowest
        if min_val == np.inf:
            return -1, min_val
        j = remaining[index]
        if row4col[j] == -1:
            sink = j
        else:
            i = row4col[j]
        SC[j] = True
        num_remaining -= 1
        remaining[index] = remaining[num_remaining]
    return sink, min_val
