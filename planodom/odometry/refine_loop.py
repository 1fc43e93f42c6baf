"""The solver's refinement (:mod:`planodom.odometry.refine`) around the consensus pose:
SDA, then the fit over every associated plane, twice (split from
:mod:`planodom.odometry.solver`).

``odometry.refinement: translation`` (the default) runs in one compiled call
(:func:`_refine_kernel`): both rounds' SDA (with scipy's assignment ported,
:mod:`planodom.lsap`), the gathered planes' fit, a degenerate step's fit again from the
prediction, and the reach test between the rounds, with the same operations as the calls
it replaces (:func:`called_refine`, kept as the fallback and the tests' reference). Left
to those calls: ``refinement: pose`` (scipy's Procrustes), the non-holonomic constraint
(BLAS products), plane arrays of another type or layout, costs scipy rejects, and a fit
whose horizontal distance from the pass's centre is within 1e-9 of the reach (numpy's
norm is a BLAS dot, whose last bit a compiled sum need not have: there the test could
go the other way).
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numba
import numpy as np

from planodom.angles import cos_of_degrees, radians
from planodom.association import strict_association
from planodom.config import PlanodomConfig
from planodom.geometry import vector_norm
from planodom.lsap import SOLVED
from planodom.odometry.pass_bounds import PassBounds
from planodom.odometry.refine import (
    _UNMEASURED,
    PlaneTranslation,
    _mode,
    _plain,
    _translation_kernel,
    plane_rotation,
    plane_translation,
)
from planodom.planes import PlaneSet
from planodom.sda_kernel import sda_kernel

#: the kernel's outcomes: refined, or left to :func:`called_refine`
_DONE, _UNDECIDED = 0, 1


class Refined(NamedTuple):
    R: np.ndarray
    fit: PlaneTranslation


def refine(
    prev: PlaneSet, curr: PlaneSet, R: np.ndarray, t: np.ndarray, measured: bool,
    bounds: PassBounds, cfg: PlanodomConfig, lateral: float,
) -> Refined:  # fmt: skip
    """Rotation and translation by weighted least squares over all planes SDA associates
    around ``(R, t)``, twice (:func:`called_refine`), in one compiled call where it
    applies (module docstring)."""
    done = compiled_refine(prev, curr, R, t, measured, bounds, cfg, lateral)
    if done is not None:
        return done
    return called_refine(prev, curr, R, t, measured, bounds, cfg, lateral)


def called_refine(
    prev: PlaneSet, curr: PlaneSet, R: np.ndarray, t: np.ndarray, measured: bool,
    bounds: PassBounds, cfg: PlanodomConfig, lateral: float,
) -> Refined:  # fmt: skip
    """Rotation and translation by weighted least squares over all planes SDA associates
    around ``(R, t)`` (:mod:`planodom.odometry.refine`), twice: the second time with the
    inlier bound around the first result when it measured the translation. A result
    beyond the motion assumption (a wrong association) is not a measurement."""
    ocfg, acfg = cfg.odometry, cfg.association
    level = cos_of_degrees(ocfg.z_plane_max_tilt_deg)
    z_min = level if ocfg.estimate_z else None
    floor_n, parallel = (
        radians(ocfg.refine_normal_floor_deg),
        radians(acfg.parallel_angle_deg),
    )
    bound = ocfg.translation_inlier_m if measured else bounds.translation
    reach = bounds.translation + acfg.offset_tol_m
    R_c, t_c = R, np.asarray(t, dtype=np.float64)
    fit = None
    for _ in range(2):
        ij = strict_association(prev, curr, R_c, acfg, t_c, bound)
        if ocfg.refinement == "pose":
            R_c = plane_rotation(prev, curr, R_c, ij, floor_n, parallel)
        fit = plane_translation(
            prev, curr, R_c, ij, t_c, z_min, ocfg.refine_offset_floor_m,
            ocfg.refine_max_sigma_m, bounds.translation**2, measured,
            ocfg.refine_unmeasured, level, bounds.prediction_var, bounds.prediction,
            lateral,
        )  # fmt: skip
        if vector_norm(fit.t[:2] - bounds.t0[:2]) > reach or abs(fit.t[2] - t_c[2]) > reach:
            fit = replace(fit, t=t_c.copy(), measured=False, z_observed=False, n_planes=0)
            break
        t_c = fit.t
        if not fit.measured and not measured:
            break
        bound = ocfg.translation_inlier_m
    assert fit is not None
    return Refined(R_c, fit)


def compiled_refine(
    prev: PlaneSet, curr: PlaneSet, R: np.ndarray, t: np.ndarray, measured: bool,
    bounds: PassBounds, cfg: PlanodomConfig, lateral: float,
) -> Refined | None:  # fmt: skip
    """:func:`called_refine` in one compiled call, or None where it does not apply
    (module docstring)."""
    ocfg, acfg = cfg.odometry, cfg.association
    arrays = (prev.normals, prev.offsets, prev.covariances, prev.centroids, prev.radii,
              curr.normals, curr.offsets, curr.covariances, curr.centroids, curr.radii)  # fmt: skip
    if ocfg.refinement != "translation" or lateral > 0 or not all(map(_plain, arrays)):
        return None
    unmeasured, var, keep_sigma, prediction = _mode(
        ocfg.refine_unmeasured, bounds.translation**2, ocfg.refine_max_sigma_m,
        bounds.prediction_var, bounds.prediction,
    )  # fmt: skip
    level = cos_of_degrees(ocfg.z_plane_max_tilt_deg)
    rest = (
        level if ocfg.estimate_z else -np.inf, ocfg.estimate_z, ocfg.refine_offset_floor_m,
        ocfg.refine_max_sigma_m, var, measured, _UNMEASURED[unmeasured], level, keep_sigma,
    )  # fmt: skip
    R_c = np.ascontiguousarray(R, dtype=np.float64)
    gates = (
        cos_of_degrees(acfg.strict_normal_deg), acfg.strict_offset_m, acfg.overlap_margin_m,
        ocfg.translation_inlier_m if measured else float(bounds.translation),
        float(ocfg.translation_inlier_m), bounds.translation + acfg.offset_tol_m, measured,
    )  # fmt: skip
    pred = np.zeros(3) if prediction is None else np.array(prediction[:3], dtype=np.float64)
    out = _refine_kernel(
        *arrays, R_c, np.array(t, dtype=np.float64), np.array(bounds.t0[:2], dtype=np.float64),
        gates, prediction is not None, pred, *rest,
    )  # fmt: skip
    status, t_fit, cov_xy, sigma_z, z_observed, fit_measured, n_planes = out
    if status != _DONE:
        return None
    fit = PlaneTranslation(t_fit, cov_xy, sigma_z, z_observed, fit_measured, n_planes)
    return Refined(R, fit)


@numba.njit(cache=True)
def _refine_kernel(
    pn, pd, pcov, pcen, pr, cn, cd, ccov, ccen, cr, R, t, t0_xy, gates, has_pred, pred,
    z_min, use_z, floor, max_sigma, var0, measured0, weak, level, keep_sigma,
):  # fmt: skip  # pragma: no cover - compiled
    """:func:`called_refine` (``refinement: translation``, no lateral constraint):
    (status, t (3,), cov_xy (2, 2), sigma_z, z_observed, measured, n_planes); status
    :data:`_UNDECIDED` (SDA's costs rejected, or the reach test within 1e-9 of its bound)
    leaves the step to the calls. ``gates``: SDA's cosine bound, offset margin, overlap
    margin, the first round's translation bound, the inlier bound, the reach, whether the
    consensus measured; ``has_pred``, ``pred`` (3,): the prediction a degenerate fit is
    solved again from (:func:`planodom.odometry.refine._degenerate`)."""
    cos_max, d_margin, o_margin, bound, inlier, reach, measured = gates
    t_c = t.copy()
    bad = (_UNDECIDED, t_c, np.zeros((2, 2)), 0.0, False, False, 0)
    for _ in range(2):
        status, ij = sda_kernel(
            pn, pd, pcen, pr, cn, cd, ccen, cr, R, t_c, cos_max, bound + d_margin, bound + o_margin
        )
        if status != SOLVED:
            return bad
        if ij.shape[0] == 0:  # plane_translation without associations
            cov = np.empty((2, 2))
            for a in range(2):
                for b in range(2):
                    cov[a, b] = (1.0 if a == b else 0.0) * var0
            t_f, sz, z_obs, meas, n_kept = t_c.copy(), np.inf, False, False, 0
        else:
            i, j = ij[:, 0], ij[:, 1]
            planes = (pn[i], pd[i], pcov[i], cn[j], cd[j], ccov[j], R)
            t_f, h_inv, flags, n_kept = _translation_kernel(
                *planes, t_c, z_min, use_z, floor, max_sigma, var0, measured0, weak, level,
                keep_sigma,
            )  # fmt: skip
            if not flags[1] and has_pred:
                t_p = np.array([pred[0], pred[1], t_c[2]])
                t_f, h_inv, flags, n_kept = _translation_kernel(
                    *planes, t_p, z_min, use_z, floor, max_sigma, var0, measured0, weak, level,
                    keep_sigma,
                )  # fmt: skip
            z_obs, meas = flags[0], flags[1]
            sz = np.sqrt(h_inv[2, 2]) if z_obs else np.inf
            cov = h_inv[:2, :2].copy()
        dx, dy = t_f[0] - t0_xy[0], t_f[1] - t0_xy[1]
        norm = np.sqrt(dx * dx + dy * dy)
        if abs(norm - reach) <= 1e-9 * reach:
            return bad
        if norm > reach or abs(t_f[2] - t_c[2]) > reach:
            return _DONE, t_c.copy(), cov, sz, False, False, 0
        t_c = t_f
        if not meas and not measured:
            break
        bound = inlier
    return _DONE, t_c, cov, sz, z_obs, meas, n_kept
