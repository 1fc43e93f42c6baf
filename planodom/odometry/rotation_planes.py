"""Which planes may seed and vote on the rotation: not those whose normal the twist sets.

With ``extraction.single_scanner_rate_sigma_deg_s`` / ``..._speed_sigma_mps`` on, a plane of
one scanner's lines carries a covariance widened by the deskewing twist's error
(:mod:`planodom.extraction.rig2d.onescanner`): its tilt about its lines is known to
degrees, its offset near the lines to the fit's noise. Such a plane is kept out of the
rotation (the LDA pairs that seed and the associations that vote,
:mod:`planodom.odometry.rotation`) and of the translation consensus built on those pairs,
and measures the translation in the refinement only (:mod:`planodom.odometry.refine`,
weighted by its covariance). The bar is the extraction's own for a plane's normal,
``extraction.max_normal_sigma_deg`` (``sqrt(trace Cov(n))``): the fit's planes all pass it,
so only the widened ones are left out. Off (the option's sigmas 0): the pairs unchanged.

With ``odometry.narrow_rotation: last`` the pairs that hold a narrow plane
(:attr:`planodom.planes.PlaneSet.narrow`, :mod:`planodom.extraction.rig2d.narrow`) are
left out the same way, unless no other pair is left: then they give the rotation (a
corridor's turn, where every wall is narrow).

The deskewing policy (:mod:`planodom.odometry.surfaces`) then ranks an epoch's unresolved
extractions by how many planes can take part in the rotation (:func:`rotation_planes`)
before their plane count: on world 178 at 2 cm, every extraction of epoch 94 was unresolved,
the one richest in one-scanner planes won the tie on plane count and became the reference,
and a reference with fewer than two planes within the bar has no LDA pair with any later
epoch: 56 epochs stayed unresolved.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.association import PairAssociations
from planodom.config import ExtractionConfig
from planodom.geometry import Plane
from planodom.planes import PlaneSet


def widened(config: ExtractionConfig) -> bool:
    """Whether the one-scanner widening is on (either of its sigmas above 0)."""
    return bool(config.single_scanner_rate_sigma_deg_s or config.single_scanner_speed_sigma_mps)


def rotation_pairs(
    prev: PlaneSet,
    curr: PlaneSet,
    lda: PairAssociations,
    config: ExtractionConfig,
    narrow_last: bool = False,
) -> PairAssociations:
    """The LDA pairs ``lda`` whose four planes' normals are known within
    ``config.max_normal_sigma_deg`` (unknown covariances pass); ``lda`` itself when the
    one-scanner widening is off or every pair passes (module docstring). With
    ``narrow_last`` (``odometry.narrow_rotation: last``) those of them without a narrow
    plane (:attr:`PlaneSet.narrow`) when any is left."""
    if narrow_last and len(lda) and (prev.narrow is not None or curr.narrow is not None):
        lda = _without_narrow(prev, curr, lda)
    if not widened(config):
        return lda
    if len(lda) == 0:
        return lda
    limit = float(np.radians(config.max_normal_sigma_deg)) ** 2
    ok_p, ok_c = _sharp(prev, limit), _sharp(curr, limit)
    keep = ok_p[lda.prev_pairs].all(axis=1) & ok_c[lda.curr_pairs].all(axis=1)
    if keep.all():
        return lda
    return PairAssociations(
        lda.prev_pairs[keep], lda.curr_pairs[keep], lda.rotations[keep], lda.weights[keep]
    )


def _without_narrow(prev: PlaneSet, curr: PlaneSet, lda: PairAssociations) -> PairAssociations:
    """The pairs of ``lda`` none of whose four planes is narrow, ``lda`` itself when every
    pair holds one (the narrow planes' pairs are the rotation's last resort)."""
    wide_p = np.ones(len(prev), bool) if prev.narrow is None else ~prev.narrow
    wide_c = np.ones(len(curr), bool) if curr.narrow is None else ~curr.narrow
    keep = wide_p[lda.prev_pairs].all(axis=1) & wide_c[lda.curr_pairs].all(axis=1)
    if keep.all() or not keep.any():
        return lda
    return PairAssociations(
        lda.prev_pairs[keep], lda.curr_pairs[keep], lda.rotations[keep], lda.weights[keep]
    )


def _sharp(planes: PlaneSet, limit: float) -> np.ndarray:
    """(K,) whether each plane's normal variance (trace) is within ``limit`` rad^2 (NaN:
    unknown, passes)."""
    var_n = np.trace(planes.covariances[:, :3, :3], axis1=1, axis2=2)
    return ~(var_n > limit)


def rotation_planes(planes: Sequence[Plane], config: ExtractionConfig) -> int:
    """How many of ``planes`` may take part in the rotation: their normal variance (trace
    of the (n, n) block of the covariance) within ``config.max_normal_sigma_deg`` squared,
    or no covariance (module docstring)."""
    limit = float(np.radians(config.max_normal_sigma_deg)) ** 2
    return sum(
        p.covariance is None or not float(np.trace(p.covariance[:3, :3])) > limit for p in planes
    )
