"""Optimal Candidate Selection by Consensus: OCSC and its weighted variant WOCSC (paper IV).

The population of associated elements ``x_k^i -> x_{k+d}^i`` (i = 1..E) undergoes one
transformation ``K`` (paper eq. 3): ``x_{k+d}^i = K (.) x_k^i``. Each candidate ``K^j``
(j = 1..C) comes from a minimal subset (expectation step); the consensus step applies
every candidate to every element and keeps the one of least summed error (paper eq. 4)::

    K* = argmin_j  sum_i  e(K^j (.) x_k^i, x_{k+d}^i) * w_k^i * w_{k+d}^i

with ``e`` the squared distance. OCSC is the unweighted case (all weights one). The
selection is deterministic: no sampling, ties go to the lowest candidate index.

Two instances of ``(.)`` used by the odometry are provided: :func:`apply_inverse_rotation`
(``K = R^-1``, matrix times normal) and :func:`apply_negative_translation` (``K = -T``,
vector added to reference points).

Option beyond the paper: ``truncate`` caps each element's error (a truncated quadratic),
so that a few gross outliers cannot outvote the rest; the default (None) is the paper's
plain squared error.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np

#: Budget of (candidate, element) pairs evaluated at once, to bound memory.
_BLOCK = 1 << 18
#: Default budget of (candidate, element) evaluations before shortlisting.
_BUDGET = 1 << 20


@dataclass(frozen=True, eq=False)
class ConsensusResult:
    """Outcome of a consensus selection.

    Attributes:
        best_index: index of the winning candidate.
        best_candidate: the winning candidate (``candidates[best_index]``).
        errors: (C,) consensus error of every candidate (weighted, possibly truncated, sum).
        element_errors: (E,) squared error of every element under the winner (untruncated,
            unweighted; NaN for elements that are undefined).
        inliers: (E,) bool, elements whose error is within the inlier tolerance.
    """

    best_index: int
    best_candidate: np.ndarray
    errors: np.ndarray
    element_errors: np.ndarray
    inliers: np.ndarray

    @property
    def best_error(self) -> float:
        """Consensus error of the winning candidate."""
        return float(self.errors[self.best_index])

    @property
    def n_inliers(self) -> int:
        """How many elements agree with the winner within the inlier tolerance."""
        return int(np.count_nonzero(self.inliers))

    @property
    def n_candidates(self) -> int:
        return len(self.errors)

    @property
    def n_elements(self) -> int:
        return len(self.element_errors)


def squared_distance(predicted: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Squared Euclidean distance over trailing axes: (C, E, ...) vs (E, ...) -> (C, E)."""
    diff = predicted - target[None]
    return np.sum(diff.reshape(diff.shape[0], diff.shape[1], -1) ** 2, axis=2)


def apply_inverse_rotation(rotations: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """``R_j^-1 n_i`` for candidate rotations (C, 3, 3) and vectors (E, 3): (C, E, 3)."""
    return np.einsum("cji,ej->cei", rotations, normals)


def apply_negative_translation(translations: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``x_i - T_j`` for candidate translations (C, D) and points (E, D): (C, E, D)."""
    return points[None, :, :] - translations[:, None, :]


def consensus(
    candidates: np.ndarray,
    source: np.ndarray,
    target: np.ndarray,
    apply: Callable[[np.ndarray, np.ndarray], np.ndarray],
    *,
    error: Callable[[np.ndarray, np.ndarray], np.ndarray] = squared_distance,
    weights: np.ndarray | None = None,
    inlier_tol: float | None = None,
    truncate: float | None = None,
    groups: np.ndarray | None = None,
    budget: int | None = _BUDGET,
    shortlist: int = 256,
) -> ConsensusResult:
    """Select the candidate transformation that best fits all associated elements.

    Args:
        candidates: (C, ...) candidate operands ``K^j`` (C >= 1).
        source: (E, ...) elements at epoch k, ``x_k^i``.
        target: (E, ...) the associated elements at epoch k + d, ``x_{k+d}^i``.
        apply: ``apply(candidates (c, ...), source (e, ...)) -> (c, e, ...)``, the operator
            ``K (.) x``; called on blocks of candidates.
        error: per-element squared error ``(c, e, ...) , (e, ...) -> (c, e)``.
        weights: (E,) non-negative weights ``w_k^i * w_{k+d}^i`` (WOCSC); None for OCSC.
        inlier_tol: an element is an inlier of the winner when ``error <= inlier_tol**2``
            (a distance, in the units of the elements); None counts every defined element.
        truncate: cap each element's error at ``truncate**2`` (a distance); None = paper.
        groups: (E,) int, optional: elements with the same group id are alternative
            associations of one element (an ambiguous LDA association ``x_k^i -> x_{k+d}^j``
            or ``-> x_{k+d}^j'``); a group contributes only its least weighted error,
            i.e. each element is scored with its best partner under the candidate.
        budget: most (candidate, element) evaluations of the exhaustive selection. Beyond
            it, every candidate is first scored on an evenly strided subset of the
            elements (whole groups), the ``shortlist`` best go on to the exhaustive score
            and the others get an error of +inf. None: always exhaustive.

    Elements with a non-finite source or target value (undefined, e.g. a reference point
    that does not exist) or with zero weight are ignored; non-finite errors count as
    infinite (capped by ``truncate`` when given).

    Returns:
        :class:`ConsensusResult`; ties between candidates go to the lowest index.
    """
    candidates = np.asarray(candidates, dtype=np.float64)
    source = np.asarray(source, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    w = _checked_weights(candidates, source, target, weights)
    cap = np.inf if truncate is None else float(truncate) ** 2
    tol2 = np.inf if inlier_tol is None else float(inlier_tol) ** 2
    kind = _KINDS.get(apply, -1) if error is squared_distance else -1
    if kind >= 0:  # the odometry's two operators: one compiled pass (_consensus_kernel)
        args = (candidates, source, target, w, cap, groups, tol2, shortlist, budget)
        done = _compiled_consensus(kind, *args)
        if done is not None:
            return done
    n_cand, n_elem = len(candidates), len(source)

    defined = np.isfinite(source.reshape(n_elem, -1)).all(axis=1)
    defined &= np.isfinite(target.reshape(n_elem, -1)).all(axis=1)
    used = np.flatnonzero(defined & (w > 0))
    gid = np.arange(n_elem) if groups is None else np.asarray(groups)
    used = used[np.argsort(gid[used], kind="stable")]  # group members side by side
    problem = _Problem(candidates, source, target, apply, error, w, cap, gid, groups is not None)

    everyone = np.arange(n_cand)
    if budget is not None and n_cand > shortlist and n_cand * len(used) > budget:
        group_rank = np.cumsum(np.concatenate(([True], gid[used][1:] != gid[used][:-1]))) - 1
        stride = int(np.ceil(n_cand * len(used) / budget))
        rough = _totals(problem, everyone, used[group_rank % stride == 0])
        chosen = np.sort(np.argsort(rough, kind="stable")[:shortlist])
        totals = np.full(n_cand, np.inf)
        totals[chosen] = _totals(problem, chosen, used)
    else:
        totals = _totals(problem, everyone, used)
    best = int(np.argmin(totals))
    best_errors, inliers = _winner_errors(problem, best, defined, tol2)
    return ConsensusResult(best, candidates[best], totals, best_errors, inliers)


def _compiled_consensus(
    kind: int,
    candidates: np.ndarray,
    source: np.ndarray,
    target: np.ndarray,
    w: np.ndarray,
    cap: float,
    groups: np.ndarray | None,
    tol2: float,
    shortlist: int,
    budget: int | None,
) -> ConsensusResult | None:
    """:func:`consensus` by :func:`_consensus_kernel` (operator ``kind``); None when the
    shortlist applies (the numpy form runs then)."""
    # C-contiguous groups (a strided view would compile a second specialisation)
    gid = np.arange(len(source)) if groups is None else np.ascontiguousarray(groups, np.int64)
    # (C, D) and (E, D) views as the kernel takes them (a 2-D C-contiguous array as it is)
    cand, src, tgt = (_rows(candidates), _rows(source), _rows(target))
    limit = -1 if budget is None else int(budget)
    ok, best, totals, best_errors, inliers = _consensus_kernel(
        kind, cand, src, tgt, w, cap, gid, tol2, shortlist, limit
    )
    if not ok:
        return None
    return ConsensusResult(best, candidates[best], totals, best_errors, inliers)


def _rows(a: np.ndarray) -> np.ndarray:
    """``a`` (N, ...) as a C-contiguous (N, D) array: ``a`` itself when it is one already
    (``np.ascontiguousarray(a.reshape(len(a), -1))``'s values without its two calls)."""
    if a.ndim == 2 and a.flags.c_contiguous:
        return a
    return np.ascontiguousarray(a.reshape(len(a), -1))


def _winner_errors(
    p: _Problem, best: int, defined: np.ndarray, tol2: float
) -> tuple[np.ndarray, np.ndarray]:
    """The winner's squared error (E,) of every element (NaN where not ``defined``) and
    its inliers (E,) within ``tol2``; for the odometry's two operators in one compiled
    pass (:func:`_best_errors_kernel`, the same bits)."""
    kind = _KINDS.get(p.apply, -1) if p.error is squared_distance else -1
    if kind >= 0:
        n_elem = len(p.source)
        return _best_errors_kernel(
            kind, p.candidates[best].reshape(-1), p.source.reshape(n_elem, -1),
            p.target.reshape(n_elem, -1), defined, tol2,
        )  # fmt: skip
    best_errors = p.error(p.apply(p.candidates[best : best + 1], p.source), p.target)[0]
    best_errors = np.where(defined, best_errors, np.nan)
    with np.errstate(invalid="ignore"):
        inliers = defined & (best_errors <= tol2)
    return best_errors, inliers


def _checked_weights(
    candidates: np.ndarray, source: np.ndarray, target: np.ndarray, weights: np.ndarray | None
) -> np.ndarray:
    """The weights (E,) (ones for None) after checking the inputs' sizes."""
    n_elem = len(source)
    if len(candidates) == 0:
        raise ValueError("consensus needs at least one candidate")
    if len(target) != n_elem:
        raise ValueError(f"consensus: {n_elem} source elements but {len(target)} targets")
    if weights is None:
        return np.ones(n_elem)
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (n_elem,) or not _finite_non_negative(w):
        raise ValueError(f"consensus: weights must be {n_elem} finite non-negative numbers")
    return w


@numba.njit(cache=True)
def _finite_non_negative(w):  # pragma: no cover - compiled
    """Whether every value of ``w`` (E,) is finite and >= 0 (numpy's two reductions and
    their wrappers cost several times this on a few weights, twice a solve)."""
    for x in w:
        if not (np.isfinite(x) and x >= 0.0):
            return False
    return True


class _Problem(NamedTuple):
    """What scoring candidates needs (see :func:`consensus`); ``cap`` is the truncation
    of the squared error, ``gid`` the group id per element, ``grouped`` whether groups
    were given."""

    candidates: np.ndarray
    source: np.ndarray
    target: np.ndarray
    apply: Callable[[np.ndarray, np.ndarray], np.ndarray]
    error: Callable[[np.ndarray, np.ndarray], np.ndarray]
    weights: np.ndarray
    cap: float
    gid: np.ndarray
    grouped: bool


def _totals(p: _Problem, cand_index: np.ndarray, elems: np.ndarray) -> np.ndarray:
    """Consensus error (len(cand_index),) of the candidates over the elements ``elems``
    (group members side by side), in blocks of at most ``_BLOCK`` evaluations; for the two
    operators of the odometry with the squared distance, in one compiled pass
    (:func:`_totals_kernel`: on a few planes the numpy blocks cost ten times their
    arithmetic)."""
    g = p.gid[elems]
    first = np.concatenate(([True], g[1:] != g[:-1])) if len(elems) else np.zeros(0, bool)
    kind = _KINDS.get(p.apply, -1) if p.error is squared_distance else -1
    if kind >= 0:
        cand = p.candidates[cand_index].reshape(len(cand_index), -1)
        src = p.source.reshape(len(p.source), -1)
        tgt = p.target.reshape(len(p.target), -1)
        return _totals_kernel(kind, cand, src, tgt, p.weights, p.cap, elems, first)
    starts = np.flatnonzero(first)
    out = np.zeros(len(cand_index))
    block = max(1, _BLOCK // max(len(elems), 1))
    for b in range(0, len(cand_index) if len(elems) else 0, block):
        idx = cand_index[b : b + block]
        e = p.error(p.apply(p.candidates[idx], p.source[elems]), p.target[elems])
        e = np.minimum(np.where(np.isfinite(e), e, np.inf), p.cap) * p.weights[elems]
        if p.grouped:
            e = np.minimum.reduceat(e, starts, axis=1)
        out[b : b + block] = e.sum(axis=1)
    return out


#: Operators :func:`_totals_kernel` evaluates: 0 ``R^-1 n``, 1 ``x - T``.
_KINDS: dict[Callable[[np.ndarray, np.ndarray], np.ndarray], int] = {
    apply_inverse_rotation: 0,
    apply_negative_translation: 1,
}


@numba.njit(cache=True)
def _totals_kernel(kind, cand, src, tgt, w, cap, elems, first):  # pragma: no cover - compiled
    """:func:`_totals` of candidates ``cand`` (C, 9) rotations ``R`` row-major (kind 0:
    ``R^T x``) or (C, D) translations (kind 1: ``x - T``) over the elements ``elems`` of
    ``src``, ``tgt`` (E, D), weights ``w`` (E,), squared errors capped at ``cap``, each
    group (``first``: where one starts) scoring its least error."""
    D = tgt.shape[1]
    out = np.zeros(len(cand))
    for c in range(len(cand)):
        total = 0.0
        best = np.inf
        for q in range(len(elems)):
            e = elems[q]
            err = 0.0
            for a in range(D):
                if kind == 0:
                    pred = cand[c, a] * src[e, 0] + cand[c, 3 + a] * src[e, 1]
                    pred += cand[c, 6 + a] * src[e, 2]
                else:
                    pred = src[e, a] - cand[c, a]
                diff = pred - tgt[e, a]
                err += diff * diff
            if not np.isfinite(err):
                err = np.inf
            err = min(err, cap) * w[e]
            if first[q]:
                if q > 0:
                    total += best
                best = err
            else:
                best = min(best, err)
        if len(elems):
            total += best
        out[c] = total
    return out


@numba.njit(cache=True)
def _best_errors_kernel(kind, cand, src, tgt, defined, tol2):  # pragma: no cover - compiled
    """The winner's squared error (E,) of every element (NaN where not ``defined``) and
    the inliers (E,) within ``tol2``, for one candidate ``cand`` (9,) a rotation ``R``
    row-major (kind 0: ``R^T x``) or (D,) a translation (kind 1: ``x - T``): numpy's
    operations in numpy's order (einsum's sum over j, then the squares summed in axis
    order), without its ~10 calls per consensus."""
    E, D = tgt.shape
    errors = np.empty(E)
    inliers = np.zeros(E, dtype=np.bool_)
    for e in range(E):
        if not defined[e]:
            errors[e] = np.nan
            continue
        err = 0.0
        for a in range(D):
            if kind == 0:
                pred = (cand[a] * src[e, 0] + cand[3 + a] * src[e, 1]) + cand[6 + a] * src[e, 2]
            else:
                pred = src[e, a] - cand[a]
            diff = pred - tgt[e, a]
            err += diff * diff
        errors[e] = err
        inliers[e] = err <= tol2
    return errors, inliers


@numba.njit(cache=True)
def _consensus_kernel(
    kind, cand, src, tgt, w, cap, gid, tol2, shortlist, budget
):  # pragma: no cover
    """:func:`consensus` for the odometry's two operators (``kind``, :data:`_KINDS`) with
    the squared distance, flattened to (C, 9) or (C, D) candidates and (E, D) elements,
    in one compiled pass: the defined elements of positive weight, ordered by group id
    (stable), every candidate's total (:func:`_totals_kernel`), the first least, and its
    element errors (:func:`_best_errors_kernel`): the same steps as the numpy form, so the
    same bits (its ~30 numpy calls cost more than the arithmetic on a few planes). The
    first value is False, and nothing computed, when the shortlist would apply (``budget``
    >= 0 and exceeded): the numpy form then runs."""
    n_elem = src.shape[0]
    defined = np.ones(n_elem, dtype=np.bool_)
    n_used = 0
    for e in range(n_elem):
        for a in range(src.shape[1]):
            if not np.isfinite(src[e, a]):
                defined[e] = False
        for a in range(tgt.shape[1]):
            if not np.isfinite(tgt[e, a]):
                defined[e] = False
        if defined[e] and w[e] > 0:
            n_used += 1
    used = np.empty(n_used, dtype=np.int64)
    k = 0
    for e in range(n_elem):
        if defined[e] and w[e] > 0:
            used[k] = e
            k += 1
    used = used[np.argsort(gid[used], kind="mergesort")]  # stable: members side by side
    n_cand = cand.shape[0]
    empty = np.zeros(0)
    if budget >= 0 and n_cand > shortlist and n_cand * n_used > budget:
        return False, -1, empty, empty, np.zeros(0, dtype=np.bool_)
    first = np.ones(n_used, dtype=np.bool_)
    for q in range(1, n_used):
        first[q] = gid[used[q]] != gid[used[q - 1]]
    totals = _totals_kernel(kind, cand, src, tgt, w, cap, used, first)
    best = int(np.argmin(totals))
    errors, inliers = _best_errors_kernel(kind, cand[best], src, tgt, defined, tol2)
    return True, best, totals, errors, inliers
