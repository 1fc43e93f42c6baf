"""Which of an epoch's estimates ``odometry.refinement: moments`` refines (beyond the paper).

By default (``moment_extractions: all``) every extraction the deskewing policy tries
(:func:`planodom.odometry.deskew.register_deskewed`) is refined as it is estimated, so the
policy chooses among refined steps: 254 refinements on world 498's 150 epochs, 17-30 %
more CPU than the default (docs/RESULTS.md ROT2D16). With ``moment_extractions:
committed`` the policy chooses among the consensus's steps, as the default does, and only
the estimate it commits is refined; its refined step then sets the next epoch's deskewing
twist, which is what the gain of the moments needs (ROT2D16: the solve and the twist
together).

``moment_after_ok: n`` (n > 0) refines an epoch's step only when the ``n`` steps before it
were OK and none of the last ``n`` epochs follows a gap in the epoch times: at a start and
after an unresolved or degenerate stretch the consensus's step is kept. There the default
is already far from the truth, and the moments' different steps led the runs of worlds 574
(a start in a decelerating turn) and 570 (the end of an 11-epoch gap) down other
extractions, 5x and 13x the default's ATE (ROT2D16).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

from planodom.geometry import Plane, invert_transform, orthonormalised
from planodom.odometry.deskew import EpochEstimate
from planodom.odometry.moment_refine import moment_refined
from planodom.odometry.relative import RelativePose, Status
from planodom.planes import PlaneSet

if TYPE_CHECKING:
    from planodom.odometry.odometry import PlaneOdometry


def settled(odometry: PlaneOdometry, k: int) -> bool:
    """Whether epoch ``k``'s step may be refined under ``odometry.moment_after_ok``: the
    ``n`` steps before it OK (so ``k > n``: a start is not) and none of epochs ``k - n +
    1 .. k`` after a gap in the epoch times; always with ``n = 0``."""
    n = odometry.config.odometry.moment_after_ok
    if n == 0:
        return True
    results = odometry.results[k - n : k] if k > n else []
    if len(results) < n or any(r is None or r.status is not Status.OK for r in results):
        return False
    return not any(i in odometry._gaps for i in range(k - n + 1, k + 1))


def refined_estimate(
    odometry: PlaneOdometry,
    result: RelativePose,
    reference_planes: Sequence[Plane],
    k: int,
    curr_planes: Sequence[Plane],
    plane_sets: tuple[PlaneSet, PlaneSet] | None,
) -> RelativePose:
    """``result`` (reference to epoch ``k``) refined by the moments when every extraction
    is refined (``moment_extractions: all``) and epoch ``k`` is :func:`settled`; else
    unchanged."""
    ocfg = odometry.config.odometry
    if ocfg.refinement != "moments" or ocfg.moment_extractions != "all":
        return result
    if not settled(odometry, k):
        return result
    return moment_refined(result, reference_planes, curr_planes, ocfg, plane_sets)


def refined_commit(odometry: PlaneOdometry, best: EpochEstimate, k: int) -> EpochEstimate:
    """``best``, the estimate epoch ``k`` commits, with its relative pose refined by the
    moments and its step ``T_{k-1}_k`` moved with it, when only committed extractions are
    refined (``moment_extractions: committed``), the pipeline is pairwise and epoch ``k`` is
    :func:`settled`; else ``best``."""
    ocfg = odometry.config.odometry
    if ocfg.refinement != "moments" or ocfg.moment_extractions != "committed":
        return best
    if not odometry.pairwise or best.relative.status is not Status.OK or not settled(odometry, k):
        return best
    sets = None
    if ocfg.moment_translation == "offsets":
        sets = (PlaneSet.from_planes(best.reference_planes), best.plane_set)
    relative = moment_refined(best.relative, best.reference_planes, best.planes, ocfg, sets)
    if relative is best.relative:
        return best
    # step = T_{k-1}_ref @ T_ref_k: the same T_{k-1}_ref, the refined T_ref_k
    T_last_ref = best.step @ invert_transform(best.relative.T_prev_curr)
    step = orthonormalised(T_last_ref @ relative.T_prev_curr)
    return replace(best, relative=relative, step=step)
