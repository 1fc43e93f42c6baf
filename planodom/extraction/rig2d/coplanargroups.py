"""The 2D rig's groups of one plane joined across the gap rule (``extraction.
merge_coplanar_groups``).

The grouping (:mod:`.grouping`) keeps in a plane only the traces connected to its seed
through gaps of at most ``max(plane_gap_m, gap_range_ratio * range)``
(:mod:`.connect`). A ground that a scanner pair sees ahead of the vehicle and another pair
behind it lies in two pieces farther apart than that, each with its own crossing seed:
the grouping returns two planes of one surface (issue 11's world 192 at 2 cm: 57 and 262
points, the same plane to 0.04 deg and 0.3 cm, in most epochs of a stretch). Two such
planes are parallel, so they are never an associable pair, and the ground counts twice
in the step.

Here two refit groups are one plane when the plane fit to both (total least squares over
their inliers' moments) passes the grouping's own tests for a trace joining a plane and
for a group: each group's inliers lie within the member tolerance of it (RMS), and its
RMS residual is within the ``max_rms`` limit. Joined groups (transitively, connected
components) are refit robustly as one (:mod:`.groupfit`). No threshold of its own; the gap
rule's other purposes stay: a seed is still never made of two far traces (both groups
hold a crossing seed of their own).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from planodom.extraction.planes.builder import PlaneFits


def _scatters(fits: PlaneFits) -> np.ndarray:
    """(G, 3, 3) centred scatters ``V diag(l) V^T`` (m^2, sums over the inliers)."""
    return np.einsum("gij,gj,gkj->gik", fits.evecs, fits.evals, fits.evecs)


def joins(fits: PlaneFits, i: int, j: int, tol_m: float, max_rms_m: float) -> bool:
    """Whether fits ``i`` and ``j`` are one plane (module docstring): the TLS plane of both
    inlier sets (from their moments) has an RMS residual of at most ``max_rms_m`` (m) and
    each set's RMS distance to it is at most ``tol_m`` (m)."""
    n = fits.count[[i, j]].astype(np.float64)
    if n.min() <= 0:
        return False
    S = _scatters(fits)[[i, j]]
    c = (n[:, None] * fits.centroid[[i, j]]).sum(axis=0) / n.sum()
    dc = fits.centroid[[i, j]] - c
    union = S.sum(axis=0) + np.einsum("k,ki,kj->ij", n, dc, dc)
    vals, vecs = np.linalg.eigh(union)
    m = vecs[:, 0]
    if np.sqrt(max(float(vals[0]), 0.0) / n.sum()) > max_rms_m:
        return False
    own = np.einsum("i,kij,j->k", m, S, m) + n * (dc @ m) ** 2  # (2,) summed squares
    return bool(np.all(np.sqrt(np.maximum(own, 0.0) / n) <= tol_m))


def coplanar_components(fits: PlaneFits, tol_m: float, max_rms_m: float) -> np.ndarray:
    """(G,) int label of each fit: fits that are one plane (:func:`joins`, transitively)
    share it; labels in order of each component's first fit."""
    G = len(fits)
    pairs = [(i, j) for i in range(G) for j in range(i + 1, G)]
    same = [(i, j) for i, j in pairs if joins(fits, i, j, tol_m, max_rms_m)]
    if not same:
        return np.arange(G)
    a, b = np.array(same).T
    graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(G, G))
    labels = connected_components(graph, directed=False)[1]
    _, first = np.unique(labels, return_index=True)
    order = np.argsort(np.argsort(first))  # component -> its rank by first fit
    return np.asarray(order[labels], dtype=np.intp)


def merged_groups(
    groups: list[np.ndarray], fits: PlaneFits, tol_m: float, max_rms_m: float
) -> list[np.ndarray] | None:
    """``groups`` (each (K_g,) segment indices) with those of one plane concatenated, in
    order of each component's first group, or None when no two are one plane."""
    if len(groups) < 2:
        return None
    labels = coplanar_components(fits, tol_m, max_rms_m)
    if labels.max() == len(groups) - 1:
        return None
    return [np.concatenate([g for g, k in zip(groups, labels, strict=True) if k == c])
            for c in range(int(labels.max()) + 1)]  # fmt: skip
