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

import numpy as np

#: Budget of (candidate, element) pairs evaluated at once, to bound memory.
_BLOCK = 1 << 18


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
) -> ConsensusResult:
    """Select the candidate transformation that best fits all associated elements.

    Args:
        candidates: (C, ...) candidate operands ``K^j`` (C >= 1).
        source: (E, ...) elements at epoch k, ``x_k^i``.
        target: (E, ...) the associated elements at epoch k + d, ``x_{k+d}^i``.
        apply: ``apply(candidates (c, ...), source (E, ...)) -> (c, E, ...)``, the operator
            ``K (.) x``; called on blocks of candidates.
        error: per-element squared error ``(c, E, ...) , (E, ...) -> (c, E)``.
        weights: (E,) non-negative weights ``w_k^i * w_{k+d}^i`` (WOCSC); None for OCSC.
        inlier_tol: an element is an inlier of the winner when ``error <= inlier_tol**2``
            (a distance, in the units of the elements); None counts every defined element.
        truncate: cap each element's error at ``truncate**2`` (a distance); None = paper.
        groups: (E,) int, optional: elements with the same group id are alternative
            associations of one element (an ambiguous LDA association ``x_k^i -> x_{k+d}^j``
            or ``-> x_{k+d}^j'``); a group contributes only its least weighted error,
            i.e. each element is scored with its best partner under the candidate.

    Elements whose error is NaN for every candidate (undefined, e.g. a reference point
    that does not exist) or whose weight is zero are ignored; other non-finite errors
    count as infinite (capped by ``truncate`` when given).

    Returns:
        :class:`ConsensusResult`; ties between candidates go to the lowest index.
    """
    candidates = np.asarray(candidates, dtype=np.float64)
    source = np.asarray(source, dtype=np.float64)
    target = np.asarray(target, dtype=np.float64)
    n_cand, n_elem = len(candidates), len(source)
    if n_cand == 0:
        raise ValueError("consensus needs at least one candidate")
    if len(target) != n_elem:
        raise ValueError(f"consensus: {n_elem} source elements but {len(target)} targets")
    w = np.ones(n_elem) if weights is None else np.asarray(weights, dtype=np.float64)
    if w.shape != (n_elem,) or np.any(w < 0) or not np.all(np.isfinite(w)):
        raise ValueError(f"consensus: weights must be {n_elem} finite non-negative numbers")
    cap = np.inf if truncate is None else float(truncate) ** 2

    block = max(1, _BLOCK // max(n_elem, 1))
    per_element = np.empty((n_cand, n_elem))
    for start in range(0, n_cand, block):
        stop = min(start + block, n_cand)
        per_element[start:stop] = error(apply(candidates[start:stop], source), target)
    defined = ~np.all(np.isnan(per_element), axis=0)
    used = defined & (w > 0)
    e = np.where(np.isfinite(per_element), per_element, np.inf)
    if groups is None:
        totals = np.minimum(e, cap)[:, used] @ w[used]
    else:
        g = np.asarray(groups)[used]
        order = np.argsort(g, kind="stable")
        weighted = (np.minimum(e[:, used], cap) * w[used])[:, order]
        starts = np.flatnonzero(np.r_[True, np.diff(g[order]) != 0]) if len(g) else []
        totals = (
            np.minimum.reduceat(weighted, starts, axis=1).sum(axis=1)
            if len(g)
            else np.zeros(n_cand)
        )
    best = int(np.argmin(totals))

    best_errors = per_element[best]
    tol2 = np.inf if inlier_tol is None else float(inlier_tol) ** 2
    with np.errstate(invalid="ignore"):
        inliers = defined & (best_errors <= tol2)
    return ConsensusResult(best, candidates[best], totals, best_errors, inliers)
