"""Small pieces of the solver's glue, compiled or with fewer numpy calls (SPEED2D9).

Each gives the values of the numpy expression it replaces, bit for bit, and that
expression is kept here (``numpy_*``) for the tests and ``experiments/
bench_glue_cuts9.py``. None involves a sum or product numpy may order or fuse otherwise
(no ``@``, ``einsum`` or ``dot``): integer arithmetic, copies, boolean tests, and one
squared distance of two components (numpy's ``norm(axis=1)`` of a row of two is
``sqrt(x0 * x0 + x1 * x1)``, the two products rounded before the sum, as the compiled
code does without fast-math). The solve calls each two to four times; numpy's calls on
a few rows cost several times their arithmetic there.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numba
import numpy as np

if TYPE_CHECKING:
    from planodom.association import PairAssociations


def pair_ids(pairs: np.ndarray) -> np.ndarray:
    """(M,) int64 one id per plane index pair ``pairs`` (M, 2) of integers (the
    translation consensus's groups): ``i * (max + 1) + j`` with ``max`` the largest
    index (at least 0), as :func:`numpy_pair_ids`."""
    if pairs.ndim != 2 or pairs.shape[1] != 2 or pairs.dtype != np.int64:
        return numpy_pair_ids(pairs)
    return _pair_ids_kernel(pairs)


def numpy_pair_ids(pairs: np.ndarray) -> np.ndarray:
    """:func:`pair_ids` in numpy (the solver's ``_pair_ids`` before SPEED2D9)."""
    return pairs[:, 0].astype(np.int64) * (int(pairs.max(initial=0)) + 1) + pairs[:, 1]


@numba.njit(cache=True)
def _pair_ids_kernel(pairs):  # pragma: no cover - compiled
    """:func:`pair_ids` of an int64 (M, 2) array (any layout): int64 arithmetic, wrapping
    as numpy's."""
    top = 0
    for k in range(pairs.shape[0]):
        top = max(top, pairs[k, 0], pairs[k, 1])
    out = np.empty(pairs.shape[0], dtype=np.int64)
    for k in range(pairs.shape[0]):
        out[k] = pairs[k, 0] * (top + 1) + pairs[k, 1]
    return out


def near_rows(cands: np.ndarray, best: int, tol: float) -> np.ndarray:
    """(E,) bool: the rows of ``cands`` (E, 2) within ``tol`` of row ``best`` (Euclidean;
    NaN: not near), as :func:`numpy_near_rows`."""
    if cands.ndim != 2 or cands.shape[1] != 2 or cands.dtype != np.float64:
        return numpy_near_rows(cands, best, tol)
    return _near_kernel(cands, int(best), float(tol))


def numpy_near_rows(cands: np.ndarray, best: int, tol: float) -> np.ndarray:
    """:func:`near_rows` in numpy (the translation's expression before SPEED2D9)."""
    return np.linalg.norm(cands - cands[best], axis=1) <= tol


@numba.njit(cache=True)
def _near_kernel(c, best, tol):  # pragma: no cover - compiled
    """:func:`near_rows` of a float64 (E, 2) array: each row's difference to row ``best``,
    its squares summed (x0^2 + x1^2, numpy's reduction over two), the root, the test."""
    out = np.empty(c.shape[0], dtype=np.bool_)
    b0, b1 = c[best, 0], c[best, 1]
    for k in range(c.shape[0]):
        d0 = c[k, 0] - b0
        d1 = c[k, 1] - b1
        out[k] = np.sqrt(d0 * d0 + d1 * d1) <= tol
    return out


def all_finite(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether every value of both float64 arrays ``a`` and ``b`` is finite, as
    ``np.isfinite(a).all() and np.isfinite(b).all()``."""
    if a.dtype != np.float64 or b.dtype != np.float64:
        return bool(np.isfinite(a).all() and np.isfinite(b).all())
    return bool(_finite_kernel(a.reshape(-1)) and _finite_kernel(b.reshape(-1)))


@numba.njit(cache=True)
def _finite_kernel(x):  # pragma: no cover - compiled
    """Whether every value of ``x`` (N,) is finite."""
    for k in range(x.shape[0]):
        if not np.isfinite(x[k]):
            return False
    return True


def appended(txy: np.ndarray, z: float) -> np.ndarray:
    """(3,) float64 ``np.append(txy, z)`` of a horizontal translation (2,) and a height:
    the same three values, without ``np.append``'s ravel and concatenation."""
    if txy.shape != (2,) or txy.dtype != np.float64:
        return np.append(txy, z)
    return np.array((txy[0], txy[1], z), dtype=np.float64)


def remapped_pairs(ij: np.ndarray, order_p: np.ndarray, order_c: np.ndarray) -> np.ndarray:
    """(L, 2) the plane associations ``ij`` (L, 2), L >= 1, mapped through the orders
    (``order_p[ij[:, 0]]``, ``order_c[ij[:, 1]]``), as :func:`numpy_remapped_pairs`."""
    if not _int64s(ij, order_p, order_c) or ij.ndim != 2 or ij.shape[1] != 2:
        return numpy_remapped_pairs(ij, order_p, order_c)
    return _remap_kernel(ij, order_p, order_c)


def numpy_remapped_pairs(ij: np.ndarray, order_p: np.ndarray, order_c: np.ndarray) -> np.ndarray:
    """:func:`remapped_pairs` in numpy (the solver's expression before SPEED2D9)."""
    return np.column_stack([order_p[ij[:, 0]], order_c[ij[:, 1]]])


def _int64s(*arrays: np.ndarray) -> bool:
    """Whether every one of ``arrays`` is an int64 ndarray (then the compiled remaps give
    numpy's values and dtype)."""
    return all(isinstance(a, np.ndarray) and a.dtype == np.int64 for a in arrays)


@numba.njit(cache=True)
def _remap_kernel(ij, order_p, order_c):  # pragma: no cover - compiled
    """:func:`remapped_pairs` of int64 arrays (numpy's index checks: an index out of range
    raises IndexError there; the solver's indices come from these orders' own sets)."""
    out = np.empty((ij.shape[0], 2), dtype=np.int64)
    for k in range(ij.shape[0]):
        out[k, 0] = order_p[ij[k, 0]]
        out[k, 1] = order_c[ij[k, 1]]
    return out


def kept_rows(mask: np.ndarray, *arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    """``a[mask]`` of each of ``arrays`` (N, ...) for a boolean ``mask`` (N,): the same
    rows copied, by one ``nonzero`` and a ``take`` per array (numpy's boolean indexing of
    a 2-D array costs about four times that on a few rows). Other masks, or arrays of
    another length, go to the boolean indexing itself (and its errors)."""
    if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_ or mask.ndim != 1:
        return tuple(a[mask] for a in arrays)
    n = mask.shape[0]
    if not all(isinstance(a, np.ndarray) and a.ndim >= 1 and len(a) == n for a in arrays):
        return tuple(a[mask] for a in arrays)
    index = mask.nonzero()[0]
    return tuple(a.take(index, axis=0) for a in arrays)


def same_pairs(a: PairAssociations, b: PairAssociations) -> bool:
    """Whether two LDA results hold the same bytes in every array (dtype and shape
    too): not ``np.array_equal``, for which -0.0 equals 0.0 and which a rotation's sign
    of zero could tell apart downstream."""
    fields = ("prev_pairs", "curr_pairs", "rotations", "weights")
    return all(_same_bytes(getattr(a, f), getattr(b, f)) for f in fields)


def _same_bytes(x: np.ndarray, y: np.ndarray) -> bool:
    return x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()


def same_float(a: float, b: float) -> bool:
    """The same float64 bits (a signed zero, a NaN too)."""
    return _same_bytes(np.asarray(a, np.float64), np.asarray(b, np.float64))
