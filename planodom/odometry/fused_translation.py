"""The solve's measured translation in two compiled calls (SPEED2D10, issue 11).

The consensus pipelines ("wocsc", "ocsc") measure the horizontal translation from the
reference points of the pairs that agree with the rotation, and the height from the
ground's associations (:mod:`planodom.odometry.translation`, :func:`planodom.odometry.
solver._elements_translation`). In numpy that is about forty calls a solve on a few rows
(the elements, their kept rows, two result dataclasses, the candidates and targets, two
consensus wrappers, the inliers' spread), each costing more than its arithmetic. Here:

1. numpy: the rotated current normals ``curr.normals[j] @ R.T`` (a BLAS product, kept
   as it was: a compiled product would change last bits);
2. one compiled call (:func:`_pairs_kernel`): the elements (``_elements_kernel``), their
   kept rows, the pair ids, the translation consensus (``_consensus_kernel``), the
   winner's neighbours, their weighted spread (``np.einsum("m,mi,mj->ij", w, d, d) /
   w.sum()`` in numpy's order: products ``(w d_i) d_j`` summed in row order, ``w.sum()``
   numpy's pairwise sum) and the height elements (``_heights_kernel``);
3. numpy: the heights each ground association gives, ``b - m @ t_xy`` (BLAS, kept);
4. one compiled call (:func:`_height_kernel`): the height consensus, its spread and
   ``solve_height`` (its two dot products of two terms, ``m0 g0 + m1 g1``, as numpy's).

The same IEEE operations in the same order as the numpy path, so the same bits (the
tests compare both on random and simulated solves). Anything the compiled path does not
cover returns None and the numpy path runs: the consensus's shortlist (more than 2^20
candidate-element evaluations), weights that are not finite and non-negative (numpy's
error), more than 128 near rows or ground associations (numpy's sum of them splits
recursively), arrays of another type or layout.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from planodom.angles import radians
from planodom.consensus import _BUDGET, ConsensusResult, _consensus_kernel
from planodom.geometry import vector_norm
from planodom.odometry.pass_bounds import PassBounds
from planodom.odometry.solver_glue import _near_kernel, _pair_ids_kernel
from planodom.odometry.translation import _elements_kernel, _heights_kernel
from planodom.planes import PlaneSet

#: :func:`planodom.consensus.consensus`'s default shortlist size.
_SHORTLIST = 256


@dataclass(frozen=True)
class MeasuredTranslation:
    """The solve's translation: horizontal translation (2,), height, covariance of the
    horizontal part (spread based), consensus, sigma of z, whether z was measured,
    and the indices of the winning pair element and height element (-1: a mean / none)."""

    txy: np.ndarray
    z: float
    cov: np.ndarray
    consensus: ConsensusResult | None
    sigma_z: float
    z_observed: bool
    best: int = -1
    height: int = -1


def fused_translation(
    prev: PlaneSet,
    curr: PlaneSet,
    R: np.ndarray,
    pp: np.ndarray,
    cp: np.ndarray,
    ij: np.ndarray,
    method: str,
    bounds: PassBounds,
    cfg: Any,
    parts: tuple | None = None,
) -> tuple[np.ndarray, MeasuredTranslation | None, bool] | None:
    """The pair elements' rows ``(i1, i2, j1, j2)`` (E, 4), the translation (None without
    elements) and whether it is a measurement, as the solver's numpy path gives them for
    the consensus ``method`` ("wocsc" or "ocsc"), or None where that path must run.
    ``parts``: :func:`fused_parts` of these arguments when the caller has them (a solve of
    the same planes, rotation and pairs with other bounds, SPEED2D15), else computed."""
    if parts is None:
        parts = fused_parts(prev, curr, R, pp, cp, ij, method, float(bounds.z_prior), cfg)
    return bounded(parts, bounds, cfg)


def fused_parts(
    prev: PlaneSet, curr: PlaneSet, R: np.ndarray, pp: np.ndarray, cp: np.ndarray,
    ij: np.ndarray, method: str, z0: float, cfg: Any,
) -> tuple | None:  # fmt: skip
    """What :func:`fused_translation` computes before its bounds' tests, which alone read
    the bounds' centre ``t0`` and reach (``z0``: the bounds' ``z_prior``, m): None (the
    numpy path), ``(pairs, None, None)`` (no elements), or ``(pairs, translation, height)``
    with the translation at ``z0`` and ``height`` the height kernel's result (None when
    the height is not estimated)."""
    arrays = (prev.normals, prev.offsets, prev.weights, prev.covariances,
              curr.normals, curr.offsets, curr.weights, curr.covariances)  # fmt: skip
    if not all(map(_plain, arrays)) or not _ints(pp, cp, ij):
        return None
    ocfg, acfg = cfg.odometry, cfg.association
    r1, r2 = curr.normals[cp[:, 0]] @ R.T, curr.normals[cp[:, 1]] @ R.T
    weighted, tol = method == "wocsc", ocfg.translation_inlier_m
    status, pairs, totals, errors, inliers, vec, hb, hm = _pairs_kernel(
        prev.normals, prev.offsets, prev.weights, curr.normals, curr.offsets, curr.weights,
        np.ascontiguousarray(r1), np.ascontiguousarray(r2), pp, cp, ij,
        float(acfg.min_line_verticality), float(np.cos(radians(ocfg.translation_min_angle_deg))),
        float(np.cos(radians(ocfg.z_plane_max_tilt_deg))), weighted, float(tol),
        float(tol) ** 2, z0, _SHORTLIST, _BUDGET,
    )  # fmt: skip
    if status == 2:
        return None
    if status == 1:
        return pairs, None, None
    best = int(vec[12])
    cons = ConsensusResult(best, vec[10:12].copy(), totals, errors, inliers)
    txy, a, g, cov = vec[0:2].copy(), vec[2:4], vec[4:6], vec[6:10].reshape(2, 2).copy()
    tr = MeasuredTranslation(txy, z0, cov, cons, np.inf, False, best)
    done = None
    if ocfg.estimate_z and len(hb):
        hz = hb - hm @ txy
        done = _height_kernel(
            prev.normals, prev.offsets, prev.weights, prev.covariances, curr.offsets,
            curr.weights, curr.covariances, ij, float(np.cos(radians(ocfg.z_plane_max_tilt_deg))),
            np.ascontiguousarray(hz), weighted, a.copy(), g.copy(),
            float(ocfg.min_sigma_translation_m), _SHORTLIST, _BUDGET,
        )  # fmt: skip
        if done[0] == 2:
            return None
    return pairs, tr, done


def bounded(
    parts: tuple | None, bounds: PassBounds, cfg: Any
) -> tuple[np.ndarray, MeasuredTranslation | None, bool] | None:
    """:func:`fused_translation`'s result from its :func:`fused_parts` and ``bounds``: the
    height kept only within the bounds' reach of their centre, and the translation a
    measurement only within it."""
    if parts is None:
        return None
    pairs, tr, done = parts
    if tr is None:
        return pairs, None, False
    reach = bounds.translation + cfg.association.offset_tol_m
    if done is not None:
        h_status, z, sigma_z, h, txy_z = done
        if h_status == 0 and not abs(z - bounds.t0[2]) > reach:
            tr = MeasuredTranslation(txy_z, z, tr.cov, tr.consensus, sigma_z, True, tr.best,
                                     int(h))  # fmt: skip
    return pairs, tr, vector_norm(tr.txy - bounds.t0[:2]) <= reach


def _plain(a: np.ndarray) -> bool:
    """A C-contiguous float64 array (one compiled specialisation)."""
    return a.dtype == np.float64 and a.flags.c_contiguous


def _ints(*arrays: np.ndarray) -> bool:
    """C-contiguous int64 (N, 2) arrays."""
    return all(
        a.dtype == np.int64 and a.ndim == 2 and a.shape[1] == 2 and a.flags.c_contiguous
        for a in arrays
    )


#: The most values :func:`_pairwise_sum` takes: numpy's ``pairwise_sum`` splits longer
#: arrays recursively, and numba's cache of a recursive function crashes on loading;
#: the kernels hand longer sums (more near rows or ground associations) to numpy.
_MAX_SUM = 128


@numba.njit(cache=True)
def _pairwise_sum(a):  # pragma: no cover - compiled
    """numpy's ``pairwise_sum`` of a contiguous float64 (N,) array, N <= 128 (else NaN):
    a plain loop under 8 values, else eight running sums combined in pairs, then the
    rest."""
    n = a.shape[0]
    if n > _MAX_SUM:
        return np.nan
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[i]
        return res
    r = a[:8].copy()
    i = 8
    while i < n - n % 8:
        for u in range(8):
            r[u] += a[i + u]
        i += 8
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        res += a[i]
        i += 1
    return res


@numba.njit(cache=True, error_model="numpy")
def _spread_kernel(d, w):  # pragma: no cover - compiled
    """The solver's ``_spread``: ``np.einsum("m,mi,mj->ij", w, d, d) / w.sum()`` of
    deviations ``d`` (M, 2), weights ``w`` (M,): einsum's products ``(w d_i) d_j`` summed
    from 0 in row order, over numpy's pairwise sum (0 / 0: NaN, as numpy)."""
    out = np.zeros((2, 2))
    for k in range(d.shape[0]):
        for u in range(2):
            for v in range(2):
                out[u, v] += (w[k] * d[k, u]) * d[k, v]
    return out / _pairwise_sum(w)


@numba.njit(cache=True)
def _weights_ok(w):  # pragma: no cover - compiled
    """Whether every weight is finite and non-negative (the consensus's check)."""
    for x in w:
        if not (np.isfinite(x) and x >= 0.0):
            return False
    return True


@numba.njit(cache=True, error_model="numpy")
def _pairs_kernel(
    pn, po, pw, cn, co, cw, r1, r2, pp, cp, ij, min_vert, cos_min, cos_tilt, weighted, tol,
    tol2, z0, shortlist, budget,
):  # fmt: skip  # pragma: no cover - compiled
    """:func:`fused_translation`'s first call: status (0 done, 1 no elements, 2 the numpy
    path must run), the kept pairs (E, 4), the consensus's totals, element errors and
    inliers, ``vec`` (13,): t_xy, a, g (2 each), the spread (4, row-major), the winning
    candidate (2) and its index; the height elements' ``b`` (H,) and ``m`` (H, 2)."""
    ok, ref_p_all, ref_c_all, slope_all, w_all = _elements_kernel(
        pn, po, pw, cn, co, cw, r1, r2, pp[:, 0].copy(), pp[:, 1].copy(), cp[:, 0].copy(),
        cp[:, 1].copy(), min_vert, cos_min,
    )  # fmt: skip
    E = int(ok.sum())
    pairs = np.empty((E, 4), dtype=np.int64)
    ref_p, ref_c = np.empty((E, 2)), np.empty((E, 2))
    slope, w = np.empty((E, 2)), np.empty(E)
    k = 0
    for e in range(ok.shape[0]):
        if ok[e]:
            pairs[k, 0], pairs[k, 1], pairs[k, 2], pairs[k, 3] = (
                pp[e, 0],
                pp[e, 1],
                cp[e, 0],
                cp[e, 1],
            )
            ref_p[k], ref_c[k], slope[k], w[k] = ref_p_all[e], ref_c_all[e], slope_all[e], w_all[e]
            k += 1
    _, hb, hm, _ = _heights_kernel(pn, po, pw, co, cw, ij, cos_tilt)
    vec = np.zeros(13)
    empty, no = np.zeros(0), np.zeros(0, dtype=np.bool_)
    if E == 0:
        return 1, pairs, empty, empty, no, vec, hb, hm
    wc = w.copy() if weighted else np.ones(E)
    if weighted and not _weights_ok(wc):
        return 2, pairs, empty, empty, no, vec, hb, hm
    a_all = ref_p - (ref_c + 0.0 * slope)
    targets = ref_c + z0 * slope
    cands = ref_p - targets
    gid = _pair_ids_kernel(pairs[:, :2].copy())
    done, best, totals, errors, inliers = _consensus_kernel(
        1, cands, ref_p, targets, wc, np.inf, gid, tol2, shortlist, budget
    )
    if not done:
        return 2, pairs, empty, empty, no, vec, hb, hm
    near = _near_kernel(cands, best, tol)
    M = int(near.sum())
    if M > _MAX_SUM:
        return 2, pairs, empty, empty, no, vec, hb, hm
    d, nw = np.empty((M, 2)), np.empty(M)
    q = 0
    for e in range(E):
        if near[e]:
            d[q, 0], d[q, 1] = cands[e, 0] - cands[best, 0], cands[e, 1] - cands[best, 1]
            nw[q] = wc[e]
            q += 1
    cov = _spread_kernel(d, nw)
    for u in range(2):
        vec[u] = a_all[best, u] - z0 * slope[best, u]
        vec[2 + u], vec[4 + u] = a_all[best, u], slope[best, u]
        vec[6 + u], vec[8 + u] = cov[0, u], cov[1, u]
        vec[10 + u] = cands[best, u]
    vec[12] = best
    return 0, pairs, totals, errors, inliers, vec, hb, hm


@numba.njit(cache=True, error_model="numpy")
def _height_kernel(
    pn, po, pw, pc, co, cw, cc, ij, cos_tilt, hz, weighted, a, g, min_sigma, shortlist, budget
):  # pragma: no cover - compiled
    """:func:`fused_translation`'s second call, the height from the H ground associations'
    heights ``hz`` (H,) at the horizontal translation: status (0 solved, 1 ill-conditioned:
    not observed, 2 the numpy path must run), z, sigma_z, the winning element and the
    horizontal translation at that z (2,)."""
    keep, b, m, w = _heights_kernel(pn, po, pw, co, cw, ij, cos_tilt)
    H = b.shape[0]
    hij = np.empty((H, 2), dtype=np.int64)
    q = 0
    for r in range(keep.shape[0]):
        if keep[r]:
            hij[q, 0], hij[q, 1] = ij[r, 0], ij[r, 1]
            q += 1
    wc = w.copy() if weighted else np.ones(H)
    txy = np.zeros(2)
    if H > _MAX_SUM or (weighted and not _weights_ok(wc)):
        return 2, 0.0, 0.0, -1, txy
    col = hz.copy().reshape((H, 1))
    done, h, _, _, _ = _consensus_kernel(
        1, col, col, np.zeros((H, 1)), wc, np.inf, np.arange(H), np.inf, shortlist, budget
    )
    if not done:
        return 2, 0.0, 0.0, -1, txy
    i, j = hij[h, 0], hij[h, 1]
    spread = np.sqrt(pc[i, 3, 3] + cc[j, 3, 3]) / abs(pn[i, 2])
    if not np.isfinite(spread):
        spread = np.sqrt(_pairwise_sum((hz - hz[h]) ** 2) / H)
    den = 1.0 - (m[h, 0] * g[0] + m[h, 1] * g[1])
    if abs(den) < 0.5:
        return 1, 0.0, 0.0, h, txy
    z = (b[h] - (m[h, 0] * a[0] + m[h, 1] * a[1])) / den
    sigma = spread
    if min_sigma > sigma:
        sigma = min_sigma
    for u in range(2):
        txy[u] = a[u] - z * g[u]
    return 0, z, sigma, h, txy
