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
from dataclasses import dataclass

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
from planodom.odometry.rotation import (
    chord,
    chordal_mean_rotation,
    rotation_angles_to,
    rotation_consensus,
    rpy_spread,
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
            horizontal translation not: no pair has a vertical-enough intersection; the
            translation is the prior's or zero).
        pipeline: the pipeline name.
        z_observed: whether the vertical translation was measured (ground plane).
        covariance: (5, 5) covariance of (roll, pitch, yaw, x, y), rad^2 / m^2, from the
            spread of the candidates that agree with the winner (plus floors); for a
            mean, the spread divided by the count.
        sigma_z: standard deviation of the vertical translation, metres (inf: unobserved).
        lda: the LDA pair associations (indices into the input plane lists).
        plane_associations: (L, 2) SDA associations (i, j) under the final pose.
        rotation_consensus, translation_consensus: consensus results (None when not run).
        n_translation_pairs: pairs that gave a reference point in both epochs.
        used_prior: the LDA bounds were applied around the prior.
        fallback: True when ``T_prev_curr`` is not measured (set by the streaming
            odometry for unresolved epochs, which it bridges by constant velocity).
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

    @property
    def rpy(self) -> np.ndarray:
        """(roll, pitch, yaw) increments, rad."""
        return rpy_from_rotation(self.T_prev_curr[:3, :3])

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


def _floor_cov(cov: np.ndarray, floors: np.ndarray) -> np.ndarray:
    return cov + np.diag(np.asarray(floors) ** 2)


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
            then bounds the motion around it (retrying without it when it leaves no
            candidate, if ``retry_without_prior``); its z fills an unobserved height.

    Returns:
        :class:`RelativePose`; index arrays refer to the input lists.
    """
    cfg = config or PlanodomConfig()
    ocfg, acfg = cfg.odometry, cfg.association
    rot_method, trans_method = pipeline_methods(ocfg.pipeline)
    prev_in, curr_in = as_plane_arrays(planes_prev), as_plane_arrays(planes_curr)
    order_p, order_c = _canonical_order(prev_in), _canonical_order(curr_in)
    prev, curr = prev_in.take(order_p), curr_in.take(order_c)
    prior = None if prior is None else np.asarray(prior, dtype=np.float64)

    used_prior = prior is not None
    lda = lenient_association(prev, curr, acfg, prior)
    if len(lda) == 0 and prior is not None and ocfg.retry_without_prior:
        lda, used_prior = lenient_association(prev, curr, acfg, None), False

    def result(T, status, **kw) -> RelativePose:
        ij = kw.pop("plane_associations", np.zeros((0, 2), dtype=np.intp))
        ij = np.column_stack([order_p[ij[:, 0]], order_c[ij[:, 1]]]) if len(ij) else ij
        return RelativePose(
            T_prev_curr=T,
            status=status,
            pipeline=ocfg.pipeline,
            lda=lda.remapped(order_p, order_c),
            plane_associations=ij,
            used_prior=used_prior,
            **kw,
        )

    z_prior = float(prior[2, 3]) if prior is not None else 0.0
    if len(lda) == 0:
        T = prior.copy() if prior is not None else np.eye(4)
        return result(T, "unresolved", z_observed=False, covariance=np.full((5, 5), np.nan),
                      sigma_z=np.inf)  # fmt: skip

    # ---------------------------------------------------------------- rotation
    inlier_angle = np.radians(ocfg.rotation_inlier_deg)
    if rot_method == "mean":
        rot_cons = None
        R = chordal_mean_rotation(lda.rotations)
        close = rotation_angles_to(lda.rotations, R) <= inlier_angle
        cov_r = rpy_spread(lda.rotations[close], R) / max(int(close.sum()), 1)
    else:
        truncate = ocfg.truncate_rotation_deg
        rot_cons, _ = rotation_consensus(
            prev, curr, lda, weighted=rot_method == "wocsc", inlier_angle=inlier_angle,
            truncate_angle=None if truncate is None else np.radians(truncate),
            best_partner=ocfg.best_partner,
        )  # fmt: skip
        R = lda.rotations[rot_cons.best_index]
        close = rotation_angles_to(lda.rotations, R) <= inlier_angle
        cov_r = rpy_spread(lda.rotations[close], R)

    # ---------------------------------------------------------------- translation
    t0 = prior[:3, 3] if used_prior else np.zeros(3)
    t_bound = acfg.prior_translation_m if used_prior else acfg.max_translation_m
    parallel = np.radians(acfg.parallel_angle_deg)
    if trans_method == "cog":
        ij = strict_association(prev, curr, R, acfg, t0, t_bound)
        elems = translation_elements(prev, curr, R, *pairs_of_associations(ij, prev, parallel),
                                     acfg.min_line_verticality)  # fmt: skip
    else:
        # LDA pairs whose both plane associations agree with R.
        c = chord(inlier_angle)
        pp, cp = lda.prev_pairs, lda.curr_pairs
        e1 = np.linalg.norm(prev.normals[pp[:, 0]] - curr.normals[cp[:, 0]] @ R.T, axis=1)
        e2 = np.linalg.norm(prev.normals[pp[:, 1]] - curr.normals[cp[:, 1]] @ R.T, axis=1)
        agree = (e1 <= c) & (e2 <= c)
        ij = lda.plane_associations(agree)
        elems = translation_elements(prev, curr, R, pp[agree], cp[agree],
                                     acfg.min_line_verticality)  # fmt: skip

    heights = height_elements(prev, curr, ij, np.radians(ocfg.z_plane_max_tilt_deg))
    use_z = ocfg.estimate_z and len(heights) > 0
    trans_cons = None
    if len(elems) == 0:
        status, txy, z = "degenerate", t0[:2].copy(), z_prior
        cov_t, sigma_z, z_observed = np.full((2, 2), np.nan), np.inf, False
    else:
        status = "ok"
        txy, z, cov_t, trans_cons, sigma_z, z_observed = _translation(
            elems, heights if use_z else None, z_prior, trans_method, ocfg
        )

    T = make_transform(R, [txy[0], txy[1], z])
    cov = np.zeros((5, 5))
    cov[:3, :3] = _floor_cov(cov_r, [np.radians(ocfg.min_sigma_rotation_deg)] * 3)
    cov[3:, 3:] = _floor_cov(cov_t, [ocfg.min_sigma_translation_m] * 2)
    final_ij = strict_association(
        prev, curr, R, acfg, T[:3, 3],
        ocfg.translation_inlier_m if status == "ok" else t_bound,
    )  # fmt: skip
    return result(
        T, status, z_observed=z_observed, covariance=cov, sigma_z=sigma_z,
        plane_associations=final_ij, rotation_consensus=rot_cons,
        translation_consensus=trans_cons, n_translation_pairs=len(elems),
    )  # fmt: skip


def _translation(elems: TranslationElements, heights, z0: float, method: str, ocfg):
    """Horizontal (and vertical) translation from the pair elements.

    Returns (txy (2,), z, cov_xy (2, 2), consensus or None, sigma_z, z_observed).
    """
    if method == "cog":
        cons = None
        cands = elems.candidates(z0)
        txy = cands.mean(axis=0)
        a, g = elems.candidates(0.0).mean(axis=0), elems.slope.mean(axis=0)
        d = cands - txy
        cov = d.T @ d / len(d) ** 2
    else:
        truncate = ocfg.truncate_translation_m
        cons = consensus(
            elems.candidates(z0), elems.ref_prev, elems.targets(z0), apply_negative_translation,
            weights=elems.weights if method == "wocsc" else None,
            inlier_tol=ocfg.translation_inlier_m, truncate=truncate,
            groups=_pair_ids(elems.prev_pairs) if ocfg.best_partner else None,
        )  # fmt: skip
        b_ = cons.best_index
        txy = cons.best_candidate.copy()
        a, g = elems.candidates(0.0)[b_], elems.slope[b_]
        d = elems.candidates(z0)
        d = d[np.linalg.norm(d - txy, axis=1) <= ocfg.translation_inlier_m] - txy
        cov = d.T @ d / len(d)

    if heights is None:
        return txy, z0, cov, cons, np.inf, False
    hz = heights.heights(txy)
    if method == "cog":
        k_b, k_m = float(heights.b.mean()), heights.m.mean(axis=0)
        spread_z = float(np.sqrt(np.mean((hz - hz.mean()) ** 2) / len(hz)))
    else:
        zc = consensus(
            hz[:, None], hz[:, None], np.zeros((len(hz), 1)), apply_negative_translation,
            weights=heights.weights if method == "wocsc" else None,
        )  # fmt: skip
        k_b, k_m = float(heights.b[zc.best_index]), heights.m[zc.best_index]
        spread_z = float(np.sqrt(np.mean((hz - hz[zc.best_index]) ** 2)))
    z = solve_height(a, g, k_b, k_m)
    if z is None:
        return txy, z0, cov, cons, np.inf, False
    sigma_z = max(spread_z, ocfg.min_sigma_translation_m)
    return a - z * g, z, cov, cons, sigma_z, True
