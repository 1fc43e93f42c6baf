"""The divide-and-conquer relative pose (paper V, Fig. 3): rotation first, then translation.

Pipelines (``config.odometry.pipeline``):

=========== ==================== ======================================
name        rotation             translation
=========== ==================== ======================================
"wocsc"     LDA, WOCSC           WOCSC over rotation-consistent LDA pairs
"sda-mean"  LDA, WOCSC           SDA, mean of the pairs' translations ("cog")
"ocsc"      LDA, OCSC            OCSC over rotation-consistent LDA pairs
"mean"      LDA, chordal mean    SDA, mean ("cog")  (ablation: no consensus)
=========== ==================== ======================================

The result is the 5-DoF increment (roll, pitch, yaw, x, y) of ``T_prev_curr``; the
vertical translation comes from near-horizontal planes (the ground) when
``estimate_z`` and one is associated, else from the prior (0 without one) and is marked
unobserved.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.angles import pose_floor, radians
from planodom.association import PairAssociations, lenient_association, strict_association
from planodom.config import PlanodomConfig
from planodom.consensus import apply_negative_translation, consensus
from planodom.geometry import Plane, make_transform, rpy_from_rotation, vector_norm
from planodom.odometry.canonical import canonical
from planodom.odometry.fused_translation import MeasuredTranslation as _Translation
from planodom.odometry.fused_translation import fused_parts, fused_translation
from planodom.odometry.nonholonomic import lateral_sigma
from planodom.odometry.pair_agreement import agreeing_pairs
from planodom.odometry.pair_rotation import candidate_pairs, rotation_weights, winner_rotation
from planodom.odometry.pass_bounds import PassBounds, pass_bounds
from planodom.odometry.propagate import pose_covariance, rotation_covariance
from planodom.odometry.refine_loop import refine
from planodom.odometry.relative import RelativePose, SolverDiagnostics, Status, replaced
from planodom.odometry.retry_status import degenerate_kept
from planodom.odometry.rotation import (
    chord,
    chordal_mean_rotation,
    rotation_angles_to,
    rotation_consensus,
)
from planodom.odometry.rotation_planes import rotation_pairs
from planodom.odometry.solver_glue import (
    all_finite,
    appended,
    kept_rows,
    near_rows,
    pair_ids,
    remapped_pairs,
    same_float,
    same_pairs,
)
from planodom.odometry.translation import (
    HeightElements,
    TranslationElements,
    height_elements,
    pairs_of_associations,
    solve_height,
    translation_elements,
)
from planodom.planes import PlaneSet, as_plane_set

#: pipeline name -> (rotation method, translation method)
PIPELINES: dict[str, tuple[str, str]] = {
    "wocsc": ("wocsc", "wocsc"),
    "sda-mean": ("wocsc", "cog"),
    "ocsc": ("ocsc", "ocsc"),
    "mean": ("mean", "cog"),
}


def pairwise_pipeline(name: str) -> str:
    """The paper pipeline this solver runs for ``odometry.pipeline`` ``name``: itself, or
    "wocsc" for "map" and "auto" (the plane-map odometry is streaming, not pairwise; a
    pair of epochs, e.g. delta > 1 for smoothing, is solved the paper's way)."""
    return "wocsc" if name in ("map", "auto") else name


def config_for_gap(config: PlanodomConfig, gap: int) -> PlanodomConfig:
    """``config`` with the association's motion bounds widened for ``gap`` epochs.

    The per-epoch bounds ``max_translation_m`` and ``max_rotation_deg`` times the gap
    (rotation at most 180 deg); the prior bounds stay (the prior carries the gap). With
    ``odometry.gap_tilt: held`` the tilt stays bounded by one epoch's rotation bound.
    """
    if gap <= 1:
        return config
    a = config.association
    changes = {
        "association.max_translation_m": a.max_translation_m * gap,
        "association.max_rotation_deg": min(a.max_rotation_deg * gap, 180.0),
    }
    if config.odometry.gap_tilt == "held":  # a vehicle's tilt does not grow with the gap
        changes["association.max_tilt_deg"] = min(a.max_tilt_deg, a.max_rotation_deg)
    return config.updated(changes, source=f"bounds for a gap of {gap} epochs")


def _spread(d: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Weighted second moment (D, D) of deviations ``d`` (M, D)."""
    return np.einsum("m,mi,mj->ij", w, d, d) / w.sum()


def estimate_relative_pose(
    planes_prev: Sequence[Plane] | PlaneSet,
    planes_curr: Sequence[Plane] | PlaneSet,
    config: PlanodomConfig | None = None,
    prior: np.ndarray | None = None,
    prior_sigma_m: float | None = None,
    step: bool = False,
    gap: int = 1,
) -> RelativePose:
    """The relative pose ``T_prev_curr`` from the planes of two epochs.

    Args:
        planes_prev: planes of epoch k in its base frame (normals towards the sensor).
        planes_curr: planes of epoch k + d in its base frame.
        config: association and odometry sections are used.
        prior: optional predicted ``T_prev_curr`` (4, 4), e.g. constant velocity. LDA
            then bounds the motion around it; when that leaves the epoch unresolved or
            degenerate and ``retry_without_prior`` is set, it is solved again with the
            prior-free bounds (a wrong prior must not lock the odometry out). The
            prior's z fills an unobserved height, its translation an unmeasured one.
        prior_sigma_m: sigma of the prior's translation, m (a prediction's), for
            ``odometry.refine_unmeasured: prediction`` (the directions planes miss).
        step: the streaming odometry's step of a vehicle (not a loop's or a skip's pair):
            a non-holonomic ``odometry.motion_model`` adds its constraint to a degenerate
            one (:func:`planodom.odometry.nonholonomic.lateral_sigma`).
        gap: epochs from the previous to the current one (a ``step``'s ``retry_accepts``).

    Returns:
        :class:`RelativePose` (``prev``, ``curr`` unset); index arrays refer to the input
        lists.
    """
    cfg = config or PlanodomConfig()
    order_p, prev = canonical(as_plane_set(planes_prev))
    order_c, curr = canonical(as_plane_set(planes_curr))
    prior = None if prior is None else np.asarray(prior, dtype=np.float64)

    lateral = lateral_sigma(cfg.odometry) if step else 0.0
    held: list = []  # the first solve's rotation, for the second's (:func:`_rotated`)
    result = _solve(prev, curr, cfg, prior, prior is not None, prior_sigma_m, lateral, held)
    assert result is not None  # None only for a rank to beat
    if result.status is not Status.OK and prior is not None and cfg.odometry.retry_without_prior:
        accepts = cfg.odometry.retry_accepts if step else "degenerate"  # a better status only
        worst = -1 if degenerate_kept(accepts, gap) else Status.DEGENERATE.rank
        floor = max(result.status.rank, worst)
        free = _solve(prev, curr, cfg, prior, False, prior_sigma_m, lateral, held, floor)
        if free is not None and free.status.rank > floor:
            result = free
    return _remapped(result, order_p, order_c)


def _remapped(result: RelativePose, order_p: np.ndarray, order_c: np.ndarray) -> RelativePose:
    """``result`` with plane indices of the sorted sets mapped back to the input order, and
    its sources."""
    ij = result.associations

    def pair(q: np.ndarray | None) -> np.ndarray | None:
        return None if q is None else np.concatenate((order_p[q[:2]], order_c[q[2:]]))

    info = result.diagnostics
    assert info is not None
    info = replaced(
        info,
        lda=info.lda.remapped(order_p, order_c),
        rotation_pair=pair(info.rotation_pair),
        translation_pair=pair(info.translation_pair),
    )
    return replaced(
        result,
        associations=remapped_pairs(ij, order_p, order_c) if len(ij) else ij,
        sources=info.sources(result.status),
        diagnostics=info,
    )


def _solve(
    prev: PlaneSet,
    curr: PlaneSet,
    cfg: PlanodomConfig,
    prior: np.ndarray | None,
    bound_by_prior: bool,
    prior_sigma_m: float | None = None,
    lateral: float = 0.0,
    held: list | None = None,
    beat: int = -1,
) -> RelativePose | None:
    """One pass of the pipeline on canonically ordered planes (indices not remapped);
    ``lateral``: the non-holonomic constraint's sigma, m (0: none); ``held``: see
    :func:`_rotated` (None: nothing reused). None once its status's rank is known to be
    ``beat`` or less (its covariance, SDA and diagnostics would never be used)."""
    ocfg, acfg = cfg.odometry, cfg.association
    name = pairwise_pipeline(ocfg.pipeline)
    rot_method, trans_method = PIPELINES[name]
    lda = lenient_association(prev, curr, acfg, prior if bound_by_prior else None)
    # not one scanner's tilted planes, nor (odometry.narrow_rotation) narrow ones if others
    lda = rotation_pairs(prev, curr, lda, cfg.extraction, ocfg.narrow_rotation == "last")
    lda = candidate_pairs(prev, curr, lda, ocfg)  # odometry.pair_rotation
    bounds = pass_bounds(cfg, prior, bound_by_prior, prior_sigma_m)
    info = SolverDiagnostics(name, lda, used_prior=bound_by_prior)
    if len(lda) == 0:
        T = prior.copy() if prior is not None else np.eye(4)
        cov = np.diag([bounds.rotation**2] * 3 + [bounds.translation**2] * 2)
        return RelativePose(T, cov, Status.UNRESOLVED, diagnostics=info)

    R, cov_r, rot_cons, ij, pp, cp = _rotated(prev, curr, lda, (rot_method, trans_method),
                                              bounds, cfg, held)  # fmt: skip
    tr_args = (prev, curr, R, pp, cp, ij, trans_method, bounds, cfg)
    pairs, tr, measured = _measured_translation(*tr_args, held=held)
    if measured:
        assert tr is not None
        txy, z, cov_t, sigma_z, z_observed = tr.txy, tr.z, tr.cov, tr.sigma_z, tr.z_observed
    else:
        kept = bounds.t0 if bounds.prediction is None else bounds.prediction
        txy, z = kept[:2].copy(), bounds.z_prior
        cov_t, sigma_z, z_observed = np.diag([bounds.translation**2] * 2), np.inf, False
    refined = None
    if ocfg.refinement != "none":
        refined = refine(prev, curr, R, appended(txy, z), measured, bounds, cfg, lateral)
        # The planes associated under the consensus pose decide: a consensus pair that
        # SDA does not confirm (a far wall's normal off by degrees) measures nothing.
        R, fit = refined.R, refined.fit
        measured = fit.measured
        if fit.n_planes:  # unmeasured directions stay near the initial value
            txy, z, cov_t = fit.t[:2], fit.t[2], fit.cov_xy
            if fit.z_observed:
                sigma_z, z_observed = fit.sigma_z, True
    if (Status.OK if measured else Status.DEGENERATE).rank <= beat:
        return None  # loses to the solve it retries (docstring)
    T = make_transform(R, [txy[0], txy[1], z])
    rot_pair = trans_pair = None
    if rot_cons is not None:
        b = rot_cons.best_index
        rot_pair = np.concatenate((lda.prev_pairs[b], lda.curr_pairs[b]))
    if measured and tr is not None and tr.best >= 0:
        trans_pair = pairs[tr.best]
    cov = np.zeros((5, 5))
    cov[:3, :3], cov[3:, 3:] = cov_r, cov_t
    if refined is None and rot_pair is not None and trans_pair is not None:
        assert tr is not None
        w = rotation_weights(prev, curr, rot_pair[:2], rot_pair[2:], ocfg)
        cov = _joint_covariance(prev, curr, rot_pair, trans_pair, tr, cov, w)
    cov = cov + pose_floor(ocfg.min_sigma_rotation_deg, ocfg.min_sigma_translation_m)
    sda_bound = ocfg.translation_inlier_m if measured else bounds.translation
    final_ij = strict_association(prev, curr, R, acfg, T[:3, 3], sda_bound)
    info = replaced(
        info, rotation_consensus=rot_cons, n_translation_pairs=len(pairs),
        translation_consensus=tr.consensus if tr is not None else None,
        rotation_pair=rot_pair, translation_pair=trans_pair,
    )  # fmt: skip
    status = Status.OK if measured else Status.DEGENERATE
    return RelativePose(
        T, cov, status, final_ij, z_observed=z_observed, sigma_z=sigma_z, diagnostics=info
    )


def _rotated(
    prev: PlaneSet, curr: PlaneSet, lda: PairAssociations, methods: tuple[str, str],
    bounds: PassBounds, cfg: PlanodomConfig, held: list | None,
) -> tuple:  # fmt: skip
    """:func:`_rotation` and :func:`_translation_pairs` of ``lda`` (``methods``: rotation,
    translation), ``(R, cov_r, consensus, ij, pp, cp)``. ``held`` (a list, None: nothing
    reused) keeps them with ``lda`` for the next solve of the same planes and config: the
    solve without the prior (:func:`estimate_relative_pose`) gets the same LDA pairs
    (the same bytes, :func:`.solver_glue.same_pairs`) in nearly every retry, and both
    are then functions of the planes, those pairs and the config alone (the pairs of
    "cog" also of the bounds: never reused), so they are returned again, not computed
    again (the same bits by construction); so are the compiled translation's results that
    do not read the bounds (:func:`_measured_translation`, which adds them to ``held``)."""
    if held and methods[1] != "cog" and same_pairs(held[0], lda):
        return held[1]
    R, cov_r, cons = _rotation(prev, curr, lda, methods[0], cfg.odometry)
    out = (R, cov_r, cons, *_translation_pairs(prev, curr, lda, R, methods[1], bounds, cfg))
    if held is not None:
        held[:] = [lda, out]
    return out


def _translation_pairs(
    prev: PlaneSet,
    curr: PlaneSet,
    lda: PairAssociations,
    R: np.ndarray,
    method: str,
    bounds: PassBounds,
    cfg: PlanodomConfig,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The plane associations (L, 2) and pair associations (P, 2), (P, 2) that give the
    translation: for "cog" every non-parallel pair of the SDA associations under ``R``,
    else the LDA pairs whose two plane associations both agree with ``R``."""
    acfg = cfg.association
    if method == "cog":
        ij = strict_association(prev, curr, R, acfg, bounds.t0, bounds.translation)
        pp, cp = pairs_of_associations(ij, prev, radians(acfg.parallel_angle_deg))
        return ij, pp, cp
    c = chord(radians(cfg.odometry.rotation_inlier_deg))
    pp, cp = lda.prev_pairs, lda.curr_pairs
    agree = agreeing_pairs(prev.normals, curr.normals, pp, cp, R, c)
    kept_pp, kept_cp = kept_rows(agree, pp, cp)
    return lda.plane_associations(agree), kept_pp, kept_cp


def _measured_translation(prev, curr, R, pp, cp, ij, method, bounds, cfg, held=None):
    """The pair elements' rows (E, 4) of the pairs ``pp`` -> ``cp`` under ``R``, then as
    :func:`_elements_translation`; consensus methods in two compiled calls (the same bits:
    :mod:`planodom.odometry.fused_translation`), else (or where those do not apply) numpy.
    ``held``: :func:`_rotated`'s, which holds this solve's ``R`` and pairs; the compiled
    calls' results (all but the bounds' tests, :func:`.fused_translation.fused_parts`) are
    kept there with the bounds' ``z_prior``, and reused for the same (a rotation reused
    by ``_rotated`` keeps them; one computed again drops them)."""
    done, z0 = None, float(bounds.z_prior)
    if method != "cog":
        if held is not None and len(held) == 3 and same_float(held[2][0], z0):
            parts = held[2][1]
        else:
            parts = fused_parts(prev, curr, R, pp, cp, ij, method, z0, cfg)
            if held is not None:
                held[2:] = [(z0, parts)]
        done = fused_translation(prev, curr, R, pp, cp, ij, method, bounds, cfg, parts)
    if done is not None:
        return done
    elems = translation_elements(prev, curr, R, pp, cp, cfg.association.min_line_verticality,
                                 radians(cfg.odometry.translation_min_angle_deg))  # fmt: skip
    heights = height_elements(prev, curr, ij, radians(cfg.odometry.z_plane_max_tilt_deg))
    return elems.pairs, *_elements_translation(prev, curr, elems, heights, method, bounds, cfg)


def _elements_translation(
    prev: PlaneSet,
    curr: PlaneSet,
    elems: TranslationElements,
    heights: HeightElements,
    method: str,
    bounds: PassBounds,
    cfg: PlanodomConfig,
) -> tuple[_Translation | None, bool]:
    """The translation from the pair elements (None without elements) and whether it is a
    measurement: not beyond the motion assumption that admitted its associations (a
    wrong association, an artefact plane)."""
    if not len(elems):
        return None, False
    ocfg = cfg.odometry
    use_heights = heights if ocfg.estimate_z and len(heights) else None
    tr = _translation(prev, curr, elems, use_heights, bounds.z_prior, method, ocfg)
    reach = bounds.translation + cfg.association.offset_tol_m
    if tr.z_observed and abs(tr.z - bounds.t0[2]) > reach:
        tr = _translation(prev, curr, elems, None, bounds.z_prior, method, ocfg)
    return tr, vector_norm(tr.txy - bounds.t0[:2]) <= reach


def _rotation(prev: PlaneSet, curr: PlaneSet, lda: PairAssociations, method: str, ocfg):
    """Rotation ``R`` (3, 3), its (roll, pitch, yaw) covariance (3, 3) and the consensus.

    Covariance: for a consensus winner, first-order propagation of its four planes' fit
    covariances when they are known; otherwise, and for the mean, the weighted spread of
    the candidates within ``rotation_inlier_deg`` (over their number for the mean).
    """
    inlier_angle = radians(ocfg.rotation_inlier_deg)
    weights = lda.weights if method != "ocsc" else np.ones(len(lda))
    if method == "mean":
        R, cons = chordal_mean_rotation(lda.rotations), None
    else:
        cons, _ = rotation_consensus(
            prev, curr, lda, weighted=method == "wocsc", inlier_angle=inlier_angle
        )
        i, j = lda.prev_pairs[cons.best_index], lda.curr_pairs[cons.best_index]
        R = winner_rotation(prev, curr, i, j, lda.rotations[cons.best_index], ocfg)
        cp, cc = prev.covariances[i], curr.covariances[j]
        if all_finite(cp, cc):
            w = rotation_weights(prev, curr, i, j, ocfg)
            return R, rotation_covariance(prev.normals[i], curr.normals[j], cp, cc, w), cons
    close = rotation_angles_to(lda.rotations, R) <= inlier_angle
    d = rpy_from_rotation(lda.rotations[close]) - rpy_from_rotation(R[None])
    d = (d + np.pi) % (2.0 * np.pi) - np.pi
    cov = _spread(d, weights[close]) if close.any() else np.zeros((3, 3))
    if method == "mean":
        cov = cov / max(int(close.sum()), 1)
    return R, cov, cons


def _translation(prev, curr, elems: TranslationElements, heights, z0: float, method, ocfg):
    """Horizontal (and vertical) translation from the pair elements.

    Every element gives ``t_xy(z) = a - z g``; the result is one element's (consensus) or
    the mean of all (cog); then z comes from the height elements when there are any.
    """
    a_all, g_all = elems.candidates(0.0), elems.slope
    cands = elems.candidates(z0)
    if method == "cog":
        cons, best = None, -1
        a, g = a_all.mean(axis=0), g_all.mean(axis=0)
        d = cands - (a - z0 * g)
        cov = d.T @ d / len(d) ** 2
    else:
        cons = consensus(
            cands, elems.ref_prev, elems.targets(z0), apply_negative_translation,
            weights=elems.weights if method == "wocsc" else None,
            inlier_tol=ocfg.translation_inlier_m, groups=pair_ids(elems.pairs[:, :2]),
        )  # fmt: skip
        best = cons.best_index
        a, g = a_all[best], g_all[best]
        w = elems.weights if method == "wocsc" else np.ones(len(elems))
        near = near_rows(cands, best, ocfg.translation_inlier_m)
        near_cands, near_w = kept_rows(near, cands, w)
        cov = _spread(near_cands - cands[best], near_w)
    txy = a - z0 * g
    if heights is None:
        return _Translation(txy, z0, cov, cons, np.inf, False, best)

    hz = heights.heights(txy)
    if method == "cog":
        h, k_b, k_m = -1, float(heights.b.mean()), heights.m.mean(axis=0)
        spread_z = float(np.sqrt(np.mean((hz - hz.mean()) ** 2) / len(hz)))
    else:
        zc = consensus(
            hz[:, None], hz[:, None], np.zeros((len(hz), 1)), apply_negative_translation,
            weights=heights.weights if method == "wocsc" else None,
        )  # fmt: skip
        h = zc.best_index
        k_b, k_m = float(heights.b[h]), heights.m[h]
        i, j = heights.ij[h]
        var_d = prev.covariances[i, 3, 3] + curr.covariances[j, 3, 3]
        spread_z = float(np.sqrt(var_d)) / abs(prev.normals[i, 2])
        if not np.isfinite(spread_z):
            spread_z = float(np.sqrt(np.mean((hz - hz[h]) ** 2)))
    z = solve_height(a, g, k_b, k_m)
    if z is None:
        return _Translation(txy, z0, cov, cons, np.inf, False, best)
    sigma_z = max(spread_z, ocfg.min_sigma_translation_m)
    return _Translation(a - z * g, z, cov, cons, sigma_z, True, best, h)


def _joint_covariance(prev, curr, rot_pair, trans_pair, tr: _Translation, fallback, weights):
    """(5, 5) covariance of (roll, pitch, yaw, x, y) propagated jointly from the planes of
    the winning rotation and translation pairs (:func:`pose_covariance`: shared planes
    counted once; ``weights``: :func:`pose_covariance`'s ``rotation_weights``), or
    ``fallback`` when a plane covariance is unknown."""
    c_p = prev.covariances[np.r_[rot_pair[:2], trans_pair[:2]]]
    c_c = curr.covariances[np.r_[rot_pair[2:], trans_pair[2:]]]
    if not (np.all(np.isfinite(c_p)) and np.all(np.isfinite(c_c))):
        return fallback
    sigma_z = tr.sigma_z if tr.z_observed else 0.0
    return pose_covariance(prev, curr, rot_pair, trans_pair, tr.z, sigma_z, weights)
