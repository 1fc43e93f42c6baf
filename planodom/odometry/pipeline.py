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
from dataclasses import dataclass, replace

import numpy as np

from planodom.association import (
    PairAssociations,
    PlaneArrays,
    as_plane_arrays,
    lenient_association,
    strict_association,
)
from planodom.config import PlanodomConfig
from planodom.consensus import ConsensusResult, apply_negative_translation, consensus
from planodom.errors import ConfigError
from planodom.geometry import Plane, make_transform, rpy_from_rotation
from planodom.odometry.propagate import (
    pose_covariance,
    rotation_covariance,
    translation_covariance,
)
from planodom.odometry.rotation import (
    chord,
    chordal_mean_rotation,
    rotation_angles_to,
    rotation_consensus,
    rpy_of,
)
from planodom.odometry.translation import (
    TranslationElements,
    height_elements,
    pairs_of_associations,
    solve_height,
    translation_elements,
)

#: pipeline name -> (rotation method, translation method)
PIPELINES: dict[str, tuple[str, str]] = {
    "wocsc": ("wocsc", "wocsc"),
    "sda-mean": ("wocsc", "cog"),
    "ocsc": ("ocsc", "ocsc"),
    "mean": ("mean", "cog"),
}

STATUSES = ("ok", "unresolved", "degenerate")


@dataclass(frozen=True, eq=False)
class RelativePose:
    """The relative pose of epoch k + d with respect to epoch k, and how it was found.

    Attributes:
        T_prev_curr: (4, 4) maps the current base frame to the previous one.
        status: "ok"; "unresolved" (no associated non-parallel pair: no measurement,
            ``T_prev_curr`` is the prior or identity); "degenerate" (rotation measured,
            horizontal translation not: no pair has a vertical-enough intersection, or
            the translation found exceeds the motion bound; the translation is then the
            prior's or zero).
        pipeline: the pipeline name.
        z_observed: whether the vertical translation was measured (ground plane).
        covariance: (5, 5) covariance of (roll, pitch, yaw, x, y), rad^2 / m^2, plus
            the floors ``min_sigma_*``. For consensus winners: first-order propagation
            of the fit covariances of the winning rotation and translation pairs' planes,
            jointly (:func:`planodom.odometry.propagate.pose_covariance`: the translation
            includes the rotation's and the height's uncertainty, planes shared by the
            two pairs count once, rotation and translation are correlated); block
            diagonal (rotation, translation) otherwise; without plane covariances, the
            weighted spread of the candidates that agree with the winner. For a mean:
            the spread over the count. DoF that were not measured (unresolved,
            degenerate) get the squared motion bound.
        sigma_z: standard deviation of the vertical translation, metres (inf: unobserved).
        lda: the LDA pair associations (indices into the input plane lists).
        plane_associations: (L, 2) SDA associations (i, j) under the final pose.
        rotation_consensus, translation_consensus: consensus results (None when not run).
        n_translation_pairs: pairs that gave a reference point in both epochs.
        used_prior: the LDA bounds were applied around the prior.
        fallback: True when ``T_prev_curr`` is not measured (set by the streaming
            odometry for unresolved epochs, which it bridges by constant velocity).
        rotation_pair, translation_pair: (4,) ``(i1, i2, j1, j2)`` of the winning pair
            association (None for a mean or when not measured).
    """

    T_prev_curr: np.ndarray
    status: str
    pipeline: str
    z_observed: bool
    covariance: np.ndarray
    sigma_z: float
    lda: PairAssociations
    plane_associations: np.ndarray
    rotation_consensus: ConsensusResult | None = None
    translation_consensus: ConsensusResult | None = None
    n_translation_pairs: int = 0
    used_prior: bool = False
    fallback: bool = False
    rotation_pair: np.ndarray | None = None
    translation_pair: np.ndarray | None = None

    @property
    def rpy(self) -> np.ndarray:
        """(roll, pitch, yaw) increments, rad."""
        return rpy_from_rotation(self.T_prev_curr[:3, :3])

    @property
    def roll(self) -> float:
        return float(self.rpy[0])

    @property
    def pitch(self) -> float:
        return float(self.rpy[1])

    @property
    def yaw(self) -> float:
        return float(self.rpy[2])

    @property
    def x(self) -> float:
        return float(self.T_prev_curr[0, 3])

    @property
    def y(self) -> float:
        return float(self.T_prev_curr[1, 3])

    @property
    def pose5(self) -> np.ndarray:
        """(roll, pitch, yaw, x, y), rad and m."""
        return np.concatenate([self.rpy, self.T_prev_curr[:2, 3]])

    @property
    def sigmas5(self) -> np.ndarray:
        """(5,) standard deviations of (roll, pitch, yaw, x, y), rad and m."""
        return np.sqrt(np.diag(self.covariance))

    @property
    def resolved(self) -> bool:
        return self.status != "unresolved"


def pipeline_methods(name: str) -> tuple[str, str]:
    """(rotation method, translation method) of a pipeline name."""
    try:
        return PIPELINES[name]
    except KeyError:
        raise ConfigError(f"odometry.pipeline: unknown pipeline {name!r}") from None


def _canonical_order(planes: PlaneArrays) -> np.ndarray:
    """A permutation sorting planes by their values, so the input order cannot matter."""
    keys = np.column_stack(
        [planes.normals, planes.offsets, planes.weights, planes.centroids, planes.radii]
    )
    return np.lexsort(keys.T[::-1])


def _pair_ids(pairs: np.ndarray) -> np.ndarray:
    """(M,) one integer id per plane index pair (M, 2)."""
    return pairs[:, 0].astype(np.int64) * (int(pairs.max(initial=0)) + 1) + pairs[:, 1]


def _spread(d: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Weighted second moment (D, D) of deviations ``d`` (M, D)."""
    return np.einsum("m,mi,mj->ij", w, d, d) / w.sum()


def estimate_relative_pose(
    planes_prev: Sequence[Plane] | PlaneArrays,
    planes_curr: Sequence[Plane] | PlaneArrays,
    config: PlanodomConfig | None = None,
    prior: np.ndarray | None = None,
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

    Returns:
        :class:`RelativePose`; index arrays refer to the input lists.
    """
    cfg = config or PlanodomConfig()
    pipeline_methods(cfg.odometry.pipeline)  # validate early
    prev_in, curr_in = as_plane_arrays(planes_prev), as_plane_arrays(planes_curr)
    order_p, order_c = _canonical_order(prev_in), _canonical_order(curr_in)
    prev, curr = prev_in.take(order_p), curr_in.take(order_c)
    prior = None if prior is None else np.asarray(prior, dtype=np.float64)

    result = _solve(prev, curr, cfg, prior, bound_by_prior=prior is not None)
    if result.status != "ok" and prior is not None and cfg.odometry.retry_without_prior:
        free = _solve(prev, curr, cfg, prior, bound_by_prior=False)
        if _rank(free) > _rank(result):
            result = free
    ij = result.plane_associations

    def pair(q: np.ndarray | None) -> np.ndarray | None:
        return None if q is None else np.r_[order_p[q[:2]], order_c[q[2:]]]

    return replace(
        result,
        lda=result.lda.remapped(order_p, order_c),
        plane_associations=np.column_stack([order_p[ij[:, 0]], order_c[ij[:, 1]]])
        if len(ij)
        else ij,
        rotation_pair=pair(result.rotation_pair),
        translation_pair=pair(result.translation_pair),
    )


def _rank(r: RelativePose) -> int:
    return {"unresolved": 0, "degenerate": 1, "ok": 2}[r.status]


def _solve(
    prev: PlaneArrays,
    curr: PlaneArrays,
    cfg: PlanodomConfig,
    prior: np.ndarray | None,
    bound_by_prior: bool,
) -> RelativePose:
    """One pass of the pipeline on canonically ordered planes (indices not remapped)."""
    ocfg, acfg = cfg.odometry, cfg.association
    rot_method, trans_method = pipeline_methods(ocfg.pipeline)
    lda = lenient_association(prev, curr, acfg, prior if bound_by_prior else None)
    t0 = prior[:3, 3] if bound_by_prior else np.zeros(3)
    t_bound = acfg.prior_translation_m if bound_by_prior else acfg.max_translation_m
    rot_bound = np.radians(acfg.prior_rotation_deg if bound_by_prior else acfg.max_rotation_deg)
    z_prior = float(prior[2, 3]) if prior is not None else 0.0
    common = {"pipeline": ocfg.pipeline, "lda": lda, "used_prior": bound_by_prior}

    if len(lda) == 0:
        T = prior.copy() if prior is not None else np.eye(4)
        cov = np.diag([rot_bound**2] * 3 + [t_bound**2] * 2)
        none = np.zeros((0, 2), dtype=np.intp)
        return RelativePose(T, "unresolved", z_observed=False, covariance=cov, sigma_z=np.inf,
                            plane_associations=none, **common)  # fmt: skip

    R, cov_r, rot_cons = _rotation(prev, curr, lda, rot_method, ocfg)

    parallel = np.radians(acfg.parallel_angle_deg)
    if trans_method == "cog":
        ij = strict_association(prev, curr, R, acfg, t0, t_bound)
        pp, cp = pairs_of_associations(ij, prev, parallel)
    else:  # LDA pairs whose both plane associations agree with R
        c = chord(np.radians(ocfg.rotation_inlier_deg))
        pp, cp = lda.prev_pairs, lda.curr_pairs
        e1 = np.linalg.norm(prev.normals[pp[:, 0]] - curr.normals[cp[:, 0]] @ R.T, axis=1)
        e2 = np.linalg.norm(prev.normals[pp[:, 1]] - curr.normals[cp[:, 1]] @ R.T, axis=1)
        agree = (e1 <= c) & (e2 <= c)
        ij, pp, cp = lda.plane_associations(agree), pp[agree], cp[agree]
    elems = translation_elements(
        prev, curr, R, pp, cp, acfg.min_line_verticality, ocfg.condition_weights,
        np.radians(ocfg.translation_min_angle_deg),
    )  # fmt: skip
    heights = height_elements(prev, curr, ij, np.radians(ocfg.z_plane_max_tilt_deg))

    tr, status = None, "degenerate"
    if len(elems):
        use_heights = heights if ocfg.estimate_z and len(heights) else None
        tr = _translation(prev, curr, elems, use_heights, z_prior, trans_method, ocfg)
        # The result must respect the motion assumption that admitted its associations;
        # beyond it (a wrong association, an artefact plane) it is not a measurement.
        reach = t_bound + acfg.offset_tol_m
        if tr.z_observed and abs(tr.z - t0[2]) > reach:
            tr = _translation(prev, curr, elems, None, z_prior, trans_method, ocfg)
        if np.linalg.norm(tr.txy - t0[:2]) <= reach:
            status = "ok"
    if status == "ok":
        txy, z, cov_t, sigma_z, z_observed = tr.txy, tr.z, tr.cov, tr.sigma_z, tr.z_observed
        if tr.best >= 0:
            cov_t = _propagated_translation_cov(
                prev, curr, elems, tr, R, cov_r, acfg.min_line_verticality, cov_t
            )
    else:
        txy, z = t0[:2].copy(), z_prior
        cov_t, sigma_z, z_observed = np.diag([t_bound**2] * 2), np.inf, False

    T = make_transform(R, [txy[0], txy[1], z])
    rot_pair = None
    if rot_cons is not None:
        rot_pair = np.r_[lda.prev_pairs[rot_cons.best_index], lda.curr_pairs[rot_cons.best_index]]
    trans_pair = None
    if status == "ok" and tr.best >= 0:
        trans_pair = np.r_[elems.prev_pairs[tr.best], elems.curr_pairs[tr.best]]
    cov = np.zeros((5, 5))
    cov[:3, :3] = cov_r
    cov[3:, 3:] = cov_t
    if rot_pair is not None and trans_pair is not None:
        cov = _joint_covariance(prev, curr, rot_pair, trans_pair, tr, cov)
    rot_floor, trans_floor = np.radians(ocfg.min_sigma_rotation_deg), ocfg.min_sigma_translation_m
    cov = cov + np.diag([rot_floor**2] * 3 + [trans_floor**2] * 2)
    sda_bound = ocfg.translation_inlier_m if status == "ok" else t_bound
    final_ij = strict_association(prev, curr, R, acfg, T[:3, 3], sda_bound)
    return RelativePose(
        T, status, z_observed=z_observed, covariance=cov, sigma_z=sigma_z,
        plane_associations=final_ij, rotation_consensus=rot_cons,
        translation_consensus=tr.consensus if tr is not None else None,
        n_translation_pairs=len(elems), rotation_pair=rot_pair, translation_pair=trans_pair,
        **common,
    )  # fmt: skip


def _rotation(prev: PlaneArrays, curr: PlaneArrays, lda: PairAssociations, method: str, ocfg):
    """Rotation ``R`` (3, 3), its (roll, pitch, yaw) covariance (3, 3) and the consensus.

    Covariance: for a consensus winner, first-order propagation of its four planes' fit
    covariances when they are known; otherwise, and for the mean, the weighted spread of
    the candidates within ``rotation_inlier_deg`` (over their number for the mean).
    """
    inlier_angle = np.radians(ocfg.rotation_inlier_deg)
    weights = lda.weights if method != "ocsc" else np.ones(len(lda))
    if method == "mean":
        R, cons = chordal_mean_rotation(lda.rotations), None
    else:
        truncate = ocfg.truncate_rotation_deg
        cons, _ = rotation_consensus(
            prev, curr, lda, weighted=method == "wocsc", inlier_angle=inlier_angle,
            truncate_angle=None if truncate is None else np.radians(truncate),
            best_partner=ocfg.best_partner,
        )  # fmt: skip
        R = lda.rotations[cons.best_index]
        i, j = lda.prev_pairs[cons.best_index], lda.curr_pairs[cons.best_index]
        cp, cc = prev.covariances[i], curr.covariances[j]
        if np.all(np.isfinite(cp)) and np.all(np.isfinite(cc)):
            return R, rotation_covariance(prev.normals[i], curr.normals[j], cp, cc), cons
    close = rotation_angles_to(lda.rotations, R) <= inlier_angle
    d = rpy_of(lda.rotations[close]) - rpy_of(R[None])
    d = (d + np.pi) % (2.0 * np.pi) - np.pi
    cov = _spread(d, weights[close]) if close.any() else np.zeros((3, 3))
    if method == "mean":
        cov = cov / max(int(close.sum()), 1)
    return R, cov, cons


@dataclass(frozen=True)
class _Translation:
    """Result of :func:`_translation`: horizontal translation (2,), height, covariance of
    the horizontal part (spread based), consensus, sigma of z, whether z was measured,
    and the indices of the winning pair element and height element (-1: a mean / none)."""

    txy: np.ndarray
    z: float
    cov: np.ndarray
    consensus: ConsensusResult | None
    sigma_z: float
    z_observed: bool
    best: int = -1
    height: int = -1


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
            inlier_tol=ocfg.translation_inlier_m, truncate=ocfg.truncate_translation_m,
            groups=_pair_ids(elems.prev_pairs) if ocfg.best_partner else None,
        )  # fmt: skip
        best = cons.best_index
        a, g = a_all[best], g_all[best]
        w = elems.weights if method == "wocsc" else np.ones(len(elems))
        near = np.linalg.norm(cands - cands[best], axis=1) <= ocfg.translation_inlier_m
        cov = _spread(cands[near] - cands[best], w[near])
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


def _joint_covariance(prev, curr, rot_pair, trans_pair, tr: _Translation, fallback):
    """(5, 5) covariance of (roll, pitch, yaw, x, y) propagated jointly from the planes of
    the winning rotation and translation pairs (:func:`pose_covariance`: shared planes
    counted once), or ``fallback`` when a plane covariance is unknown."""
    c_p = prev.covariances[np.r_[rot_pair[:2], trans_pair[:2]]]
    c_c = curr.covariances[np.r_[rot_pair[2:], trans_pair[2:]]]
    if not (np.all(np.isfinite(c_p)) and np.all(np.isfinite(c_c))):
        return fallback
    sigma_z = tr.sigma_z if tr.z_observed else 0.0
    return pose_covariance(prev, curr, rot_pair, trans_pair, tr.z, sigma_z)


def _propagated_translation_cov(prev, curr, elems, tr: _Translation, R, cov_r, min_vert, fallback):
    """Covariance (2, 2) of the winning pair's translation from its planes' covariances
    (and the rotation's and height's), or ``fallback`` when a covariance is unknown."""
    pp, cp = elems.prev_pairs[tr.best], elems.curr_pairs[tr.best]
    c_p, c_c = prev.covariances[pp], curr.covariances[cp]
    if not (np.all(np.isfinite(c_p)) and np.all(np.isfinite(c_c)) and np.all(np.isfinite(cov_r))):
        return fallback
    sigma_z = tr.sigma_z if tr.z_observed else 0.0
    return translation_covariance(prev, curr, pp, cp, c_p, c_c, R, tr.z, cov_r, sigma_z, min_vert)
