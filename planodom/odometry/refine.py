"""Weighted least squares over all associated planes, after the consensus (beyond the paper).

The consensus (:mod:`planodom.consensus`) keeps one candidate: one pair's rotation and one
pair's reference point, so the other planes only vote. Once the associations are known
(SDA under the consensus pose), every associated plane measures the motion, as in the
oracle (:mod:`planodom.oracle`):

- rotation: the weighted orthogonal Procrustes fit of the previous normals to the rotated
  current ones (``scipy.spatial.transform.Rotation.align_vectors``), weights the inverse
  variance of each association's normals;
- translation: with ``p_prev = R p_curr + t`` a plane association ``(i, j)`` gives
  ``m . t = d_j - d_i`` (``m`` the mean of ``n_i`` and ``R n_j``): a linear equation,
  weighted by the inverse variance of ``d_i - d_j + m . t`` propagated from both planes'
  ``(n, d)`` covariances, plus ``offset_floor_m`` squared for what a fit's covariance does
  not hold (deskewing, a plane's bend).

No pair has to cut at a large angle: walls a few degrees apart in yaw measure the
horizontal translation together, and the normal matrix says how well. A horizontal
direction counts as measured when its standard deviation is at most ``max_sigma_m``. The
initial value (the consensus's or the prior's) enters as a prior as wide as the motion
bound: a direction the planes hardly measure stays near it, and a corridor still
measures its cross-track offset (the epoch is then degenerate). The vertical is solved
jointly when an up-facing, near-horizontal plane (the ground) is associated, else it
keeps its initial value.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from planodom.odometry.nonholonomic import KernelPlanes, with_lateral
from planodom.odometry.refine_rotation import (  # noqa: F401 - plane_rotation re-exported
    _FALLBACK_VAR_D,
    _FALLBACK_VAR_N,
    normal_variances,
    plane_rotation,
)
from planodom.planes import PlaneSet


@dataclass(frozen=True, eq=False)
class PlaneTranslation:
    """Result of :func:`plane_translation`.

    Attributes:
        t: (3,) translation of ``T_prev_curr``, m.
        cov_xy: (2, 2) covariance of its horizontal part, m^2 (the initial value's
            directions that were not measured get ``unmeasured_var``).
        sigma_z: m (inf when not observed). z_observed: the ground was associated.
        measured: every horizontal direction measured (at most ``max_sigma_m``).
        n_planes: associations used.
    """

    t: np.ndarray
    cov_xy: np.ndarray
    sigma_z: float
    z_observed: bool
    measured: bool
    n_planes: int


def plane_translation(
    prev: PlaneSet,
    curr: PlaneSet,
    R: np.ndarray,
    ij: np.ndarray,
    t0: np.ndarray,
    z_normal_min: float | None,
    offset_floor_m: float,
    max_sigma_m: float,
    unmeasured_var: float,
    consensus_measured: bool = False,
    unmeasured: str = "prior",
    level_min: float = 0.866,
    prediction_var: float | None = None,
    predicted: np.ndarray | None = None,
    lateral_sigma_m: float = 0.0,
) -> PlaneTranslation:
    """Translation by weighted least squares over the plane associations ``ij`` (L, 2).

    Each association's weight is the inverse variance of ``d_i - d_j + m . t`` (first
    order from both planes' ``(n, d)`` covariances, fallback variances where unknown) plus
    ``offset_floor_m`` squared; the worst association is dropped while its normalised
    residual exceeds :data:`_OUTLIER_CHI2` and three stay (a plane matched to a nearly
    coplanar neighbour, or fitted across two surfaces, would otherwise bias every
    direction it touches: on the noise-free paper loop one such association moved an epoch
    by 1.4 mm). The arithmetic runs in one compiled kernel (:func:`_translation_kernel`):
    with ~5 planes, the ~40 small numpy calls it replaces cost ten times its arithmetic.

    Args:
        R: (3, 3) ``R_prev_curr``. t0: (3,) initial translation, m.
        z_normal_min: associations whose previous normal has ``n_z`` at least this are
            ground-like and let z be solved; None: z is not estimated.
        offset_floor_m: added (squared) to every association's offset variance, m.
        max_sigma_m: largest standard deviation of a measured horizontal direction, m.
        unmeasured_var: variance of ``t0``'s horizontal part, m^2 (a prior: the planes
            move the weak directions only as far as they measure them).
        consensus_measured: the consensus measured the translation; it decides when a
            plane's covariance is unknown (then the fallback variances are guesses).
        unmeasured: when not every horizontal direction is measured (``odometry.
            refine_unmeasured``): "prior": the planes' weak information pulls the
            unmeasured ones from ``t0`` against the prior; "kept": they keep ``t0``
            exactly, the others (and z) are solved with them held; "walls": x, y from
            the planes that are not level (and the prior), then z with x, y held;
            "prediction" (with ``predicted`` and ``prediction_var``, else "prior"): a
            horizontal direction the planes measure less well than the prediction
            (sigma above ``sqrt(prediction_var)``, capped at ``unmeasured_var``) keeps
            the prediction's value exactly, the others (and z) are solved with it held;
            ``cov_xy`` is the planes' information with the prediction's as the prior.
        level_min: a plane is level (floor, ceiling) when ``|m_z|`` is at least this.
        prediction_var: variance of the prediction's horizontal part, m^2.
        predicted: (3,) the predicted translation, m (its x, y are what "prediction"
            keeps; ``t0`` stays the consensus's, around which the planes associated).
        lateral_sigma_m: a vehicle's constraint's sigma, m, in a degenerate step (0: none).
    """
    unmeasured, unmeasured_var, keep_sigma, prediction = _mode(
        unmeasured, unmeasured_var, max_sigma_m, prediction_var, predicted
    )
    t0 = np.asarray(t0, dtype=np.float64)
    if len(ij) == 0:
        return PlaneTranslation(t0.copy(), np.eye(2) * unmeasured_var, np.inf, False, False, 0)
    i, j = ij[:, 0], ij[:, 1]
    R_c = np.ascontiguousarray(R, dtype=np.float64)
    rest = (
        -np.inf if z_normal_min is None else float(z_normal_min), z_normal_min is not None,
        offset_floor_m, max_sigma_m, unmeasured_var, consensus_measured,
        _UNMEASURED[unmeasured], level_min, keep_sigma,
    )  # fmt: skip
    fit = gathered_fit(prev, curr, i, j, R_c, t0, rest)
    if fit is None or not fit[2][1]:
        args = (
            prev.normals[i], prev.offsets[i], prev.covariances[i],
            curr.normals[j], curr.offsets[j], curr.covariances[j], R_c,
        )  # fmt: skip
        fit = _translation_kernel(*args, t0, *rest) if fit is None else fit
        if not fit[2][1]:
            fit = _degenerate(args, rest, t0, prediction, lateral_sigma_m, fit)
    t, h_inv, flags, n_kept = fit
    z_observed, measured = bool(flags[0]), bool(flags[1])
    sigma_z = float(np.sqrt(h_inv[2, 2])) if z_observed else np.inf
    return PlaneTranslation(t, h_inv[:2, :2].copy(), sigma_z, z_observed, measured, n_kept)


def _degenerate(
    args: KernelPlanes,
    rest: tuple[Any, ...],
    t0: np.ndarray,
    prediction: np.ndarray | None,
    lateral_sigma_m: float,
    fit: tuple[np.ndarray, np.ndarray, np.ndarray, int],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """:func:`plane_translation`'s kernel ``fit`` (t, inverse normal matrix, flags, count)
    of a degenerate step solved again: from the prediction's x, y (the prior's centre,
    what an unmeasured direction keeps; the measured ones do not depend on it), then,
    with ``lateral_sigma_m`` > 0, with the non-holonomic constraint of a vehicle as one
    more association (:mod:`planodom.odometry.nonholonomic`; status and count stay the
    planes'): a direction it measures is solved, not kept from the prediction."""
    if prediction is not None:
        t0 = np.array([prediction[0], prediction[1], t0[2]])
        fit = _translation_kernel(*args, t0, *rest)
    if lateral_sigma_m > 0 and not fit[2][1]:
        lateral = with_lateral(args, args[6], lateral_sigma_m)
        t, h_inv, flags, _ = _translation_kernel(*lateral, t0, *rest)
        fit = (t, h_inv, np.array([flags[0], fit[2][1]]), fit[3])
    return fit


def _mode(
    unmeasured: str,
    var: float,
    max_sigma_m: float,
    prediction_var: float | None,
    predicted: np.ndarray | None,
) -> tuple[str, float, float, np.ndarray | None]:
    """:func:`plane_translation`'s ``unmeasured`` as the kernel runs it: the mode, the
    prior's variance, the sigma above which a direction is kept, and the prediction (3,)
    (None: not solved again from it). "prediction" is "kept" with the prediction's sigma
    (at most ``var``'s) as the threshold, or "prior" without a prediction."""
    if unmeasured != "prediction":
        return unmeasured, var, max_sigma_m, None
    if prediction_var is None or predicted is None:
        return "prior", var, max_sigma_m, None
    var = min(prediction_var, var)
    return "kept", var, float(np.sqrt(var)), np.asarray(predicted, dtype=np.float64)


#: ``unmeasured`` of :func:`plane_translation` as the kernel's code.
_UNMEASURED = {"prior": 0, "kept": 1, "walls": 2}

#: chi2(1) at 0.999: an association whose offset residual is beyond this (in its own
#: sigmas) after the others are fitted is not kept.
_OUTLIER_CHI2 = 10.83


@numba.njit(cache=True)
def _translation_kernel(
    n_i, d_i, c_i, n_j, d_j, c_j, R, t0, z_min, use_z, floor, max_sigma, var0, measured0,
    weak, level, keep_sigma,
):  # fmt: skip  # pragma: no cover - compiled
    """:func:`plane_translation` of the L associations given as their planes' normals
    (L, 3), offsets (L,) and (n, d) covariances (L, 4, 4). Returns t (3,), the inverse
    normal matrix (3, 3) (x, y block: the horizontal covariance; [2, 2]: var z when
    observed), flags (z observed, measured) and the number of associations kept;
    ``measured0``: the consensus measured the translation; ``weak``: ``unmeasured`` of
    :func:`plane_translation` as 0 / 1 / 2 (prior / kept / walls), ``level``: its
    ``level_min``."""
    L = len(d_i)
    m = np.empty((L, 3))
    b = np.empty(L)
    w = np.empty(L)
    a_i = np.empty(4)
    a_j = np.empty(4)
    for a in range(3):
        a_i[a] = 0.5 * t0[a]
        a_j[a] = 0.5 * (R[0, a] * t0[0] + R[1, a] * t0[1] + R[2, a] * t0[2])
    a_i[3], a_j[3] = 1.0, -1.0
    fallback = _FALLBACK_VAR_N * (t0[0] ** 2 + t0[1] ** 2 + t0[2] ** 2) / 2.0
    fallback += 2.0 * _FALLBACK_VAR_D
    finite = np.ones(L, dtype=np.bool_)
    for k in range(L):
        norm = 0.0
        for a in range(3):
            m[k, a] = n_i[k, a] + R[a, 0] * n_j[k, 0] + R[a, 1] * n_j[k, 1] + R[a, 2] * n_j[k, 2]
            norm += m[k, a] ** 2
        norm = np.sqrt(norm)
        for a in range(3):
            m[k, a] /= norm
        b[k] = d_j[k] - d_i[k]
        var = 0.0
        for u in range(4):
            for v in range(4):
                var += a_i[u] * c_i[k, u, v] * a_i[v] + a_j[u] * c_j[k, u, v] * a_j[v]
                finite[k] &= np.isfinite(c_i[k, u, v]) and np.isfinite(c_j[k, u, v])
        if not np.isfinite(var):
            var = fallback
        w[k] = 1.0 / (var + floor**2)
    ground = np.zeros(L, dtype=np.bool_)
    for k in range(L):
        ground[k] = use_z and m[k, 2] >= z_min
    free = 3 if ground.any() else 2
    keep = _inliers_kernel(m, b, w, t0, free)
    A = np.zeros((3, 3))
    all_finite = True
    n_kept = 0
    z_observed = False
    for k in range(L):
        if keep[k]:
            n_kept += 1
            all_finite &= finite[k]
            z_observed |= ground[k]
            for u in range(3):
                for v in range(3):
                    A[u, v] += w[k] * m[k, u] * m[k, v]
    # Horizontal information: the Schur complement of z when z is solved, else A_xy.
    A_xy = A[:2, :2].copy()
    if z_observed:
        for u in range(2):
            for v in range(2):
                A_xy[u, v] -= A[u, 2] * A[2, v] / A[2, 2]
    lam = np.linalg.eigvalsh(A_xy)
    measured = lam[0] * max_sigma**2 >= 1.0
    if not all_finite:
        # Without the fits' covariances the precision is a guess: the consensus decides.
        measured = (measured or measured0) and lam[0] > 1e-9 * lam[1]
    free = 3 if z_observed else 2
    # Unless the planes measure every direction, the initial value is a prior of variance
    # ``var0`` (``unmeasured_var``) on x, y: what keeps an unmeasured direction where it
    # was (when they do, it is left out: noise-free planes give the exact translation).
    prior = 0.0 if measured else 1.0 / var0
    H = A[:free, :free].copy()
    H[0, 0] += prior
    H[1, 1] += prior
    g = np.zeros(free)
    for k in range(L):
        if keep[k]:
            r = w[k] * (b[k] - (m[k, 0] * t0[0] + m[k, 1] * t0[1] + m[k, 2] * t0[2]))
            for u in range(free):
                g[u] += m[k, u] * r
    H_inv = np.linalg.inv(H)
    t = t0.copy()
    h_out = np.full((3, 3), np.inf)
    for u in range(free):
        for v in range(free):
            t[u] += H_inv[u, v] * g[v]
            h_out[u, v] = H_inv[u, v]
    if weak == 1 and not measured:
        # The unmeasured horizontal directions keep t0 exactly: the update is solved in the
        # span of the measured ones (and z when solved), where the planes' information is.
        lam_w, V = np.linalg.eigh(A_xy)
        cols = 0
        B = np.zeros((free, free))
        for c in range(2):
            if lam_w[c] * keep_sigma**2 >= 1.0:
                B[0, cols], B[1, cols] = V[0, c], V[1, c]
                cols += 1
        if free == 3:
            B[2, cols] = 1.0
            cols += 1
        t = t0.copy()
        if cols:
            M = np.zeros((cols, cols))
            y = np.zeros(cols)
            for c in range(cols):
                for e in range(cols):
                    for u in range(free):
                        for v in range(free):
                            M[c, e] += B[u, c] * A[u, v] * B[v, e]
                for u in range(free):
                    y[c] += B[u, c] * g[u]
            x = np.linalg.solve(M, y)
            for u in range(free):
                for c in range(cols):
                    t[u] += B[u, c] * x[c]
    if weak == 2 and not measured:
        # Level planes (|m_z| >= level: floor, ceiling) inform x, y only through their tilt,
        # with ~1 / sin(tilt) times their offset's error: here x, y come from the other
        # planes and the prior, then z from all of them with x, y held.
        A_w = np.zeros((2, 2))
        g_w = np.zeros(2)
        for k in range(L):
            if keep[k] and abs(m[k, 2]) < level:
                r = w[k] * (b[k] - (m[k, 0] * t0[0] + m[k, 1] * t0[1] + m[k, 2] * t0[2]))
                for u in range(2):
                    g_w[u] += m[k, u] * r
                    for v in range(2):
                        A_w[u, v] += w[k] * m[k, u] * m[k, v]
        A_w[0, 0] += 1.0 / var0
        A_w[1, 1] += 1.0 / var0
        d_xy = np.linalg.solve(A_w, g_w)
        t = t0.copy()
        t[0] += d_xy[0]
        t[1] += d_xy[1]
        if z_observed:
            num, den = 0.0, 0.0
            for k in range(L):
                if keep[k]:
                    r = b[k] - (m[k, 0] * t[0] + m[k, 1] * t[1] + m[k, 2] * t0[2])
                    num += w[k] * m[k, 2] * r
                    den += w[k] * m[k, 2] ** 2
            t[2] = t0[2] + num / den
    flags = np.array([z_observed, measured])
    return t, h_out, flags, n_kept


@numba.njit(cache=True)
def _inliers_kernel(m, b, w, t0, free):  # pragma: no cover - compiled
    """(L,) bool: the associations kept, dropping the worst one while its normalised
    residual ``w (b - m . t)^2`` exceeds :data:`_OUTLIER_CHI2` and three stay. Fitted as
    in :func:`plane_translation`, without a prior (a direction no kept plane measures
    keeps ``t0``): least squares with singular values below 1e-9 of the largest cut."""
    L = len(b)
    keep = np.ones(L, dtype=np.bool_)
    n_keep = L
    e2 = np.empty(L)
    while n_keep > 3:
        A = np.empty((n_keep, free))
        y = np.empty(n_keep)
        r = 0
        for k in range(L):
            if keep[k]:
                s = np.sqrt(w[k])
                for u in range(free):
                    A[r, u] = m[k, u] * s
                y[r] = s * (b[k] - (m[k, 0] * t0[0] + m[k, 1] * t0[1] + m[k, 2] * t0[2]))
                r += 1
        x = np.linalg.lstsq(A, y, rcond=1e-9)[0]
        t = t0.copy()
        for u in range(free):
            t[u] += x[u]
        worst, worst_e = -1, -1.0
        for k in range(L):
            e2[k] = w[k] * (b[k] - (m[k, 0] * t[0] + m[k, 1] * t[1] + m[k, 2] * t[2])) ** 2
            if keep[k] and e2[k] > worst_e:
                worst, worst_e = k, e2[k]
        if worst_e <= _OUTLIER_CHI2:
            break
        keep[worst] = False
        n_keep -= 1
    return keep


def gathered_fit(
    prev: PlaneSet, curr: PlaneSet, i: np.ndarray, j: np.ndarray, R: np.ndarray,
    t0: np.ndarray, rest: tuple[Any, ...],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int] | None:  # fmt: skip
    """:func:`_translation_kernel` of the associations ``i`` -> ``j`` (L,) with the planes'
    rows gathered in the compiled call (the same copies numpy's six fancy indexings make,
    SPEED2D9: they cost as much as the kernel), or None when an array is not a writeable
    C-contiguous float64 one (int64 indices), or an index is outside ``[0, K)``: then the
    caller gathers in numpy (and its errors)."""
    arrays = (prev.normals, prev.offsets, prev.covariances, curr.normals, curr.offsets,
              curr.covariances)  # fmt: skip
    if i.dtype != np.int64 or j.dtype != np.int64 or not all(map(_plain, arrays)):
        return None
    ok, t, h_inv, flags, n_kept = _gathered_kernel(*arrays, i, j, R, t0, *rest)
    return (t, h_inv, flags, n_kept) if ok else None


def _plain(a: np.ndarray) -> bool:
    """A writeable C-contiguous float64 array (one compiled specialisation)."""
    return a.dtype == np.float64 and a.flags.c_contiguous and a.flags.writeable


@numba.njit(cache=True)
def _gathered_kernel(
    pn, pd, pc, cn, cd, cc, i, j, R, t0, z_min, use_z, floor, max_sigma, var0, measured0,
    weak, level, keep_sigma,
):  # fmt: skip  # pragma: no cover - compiled
    """:func:`gathered_fit`: False (and empty results) when an index is outside the
    planes; else True and :func:`_translation_kernel` of the gathered rows."""
    for k in range(i.shape[0]):
        if i[k] < 0 or i[k] >= pd.shape[0] or j[k] < 0 or j[k] >= cd.shape[0]:
            return False, np.zeros(3), np.zeros((3, 3)), np.zeros(2, np.bool_), 0
    t, h_inv, flags, n_kept = _translation_kernel(
        pn[i], pd[i], pc[i], cn[j], cd[j], cc[j], R, t0, z_min, use_z, floor, max_sigma,
        var0, measured0, weak, level, keep_sigma,
    )  # fmt: skip
    return True, t, h_inv, flags, n_kept
