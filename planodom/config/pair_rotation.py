"""How a pair association's candidate rotation uses its normals (a field of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.odometry_guards` is.
"""

from __future__ import annotations

from typing import Literal

from planodom.config.motion_model import MotionModelConfig


class PairRotationConfig(MotionModelConfig):
    """The candidate rotation of an LDA pair (field of ``odometry``)."""

    pair_rotation: Literal["first", "weighted", "winner"] = "first"
    """Pairwise pipelines: the candidate rotation of each LDA pair association
    ``(i1, i2) -> (j1, j2)`` that the rotation consensus scores. ``first`` (the paper's,
    eq. 1): ``U_k U_{k+d}^T`` with ``U = [n1, n2', n1 x n2]``, which fits the first normal
    exactly, so the first plane's normal error goes whole into the rotation.
    ``weighted``: the rotation that fits both normal associations weighted by their
    inverse normal variances (both planes', plus ``refine_normal_floor_deg`` squared), a
    weighted Wahba/Procrustes solution in closed form
    (:mod:`planodom.odometry.pair_rotation`); the winner's stated covariance is
    propagated through it. ``winner``: the consensus over the paper's candidates (the
    same winner), then the winner's rotation fitted to both its normals the same way
    (weighted candidates lower every pair's own misfit, walls-only pairs the most, and
    win more steps). The association's gates stay the paper's. ``weighted`` is off: on
    the 2D-rig worlds 180-198 and 20-38 (150 epochs) the per-epoch rotation improves
    (median rms 0.86x at 6 mm, 0.89x at 2 cm) but the ATE does not (geometric mean of the
    ratios 0.93 / 1.03; at 6 mm worlds 22, 180 and 186 more than twice worse): its rule
    fails (docs/RESULTS.md, WPROC). ``winner`` is off too: on worlds 160-178 ATE 0.72 / 0.86
    in geometric mean, but unresolved epochs 11 -> 13 / 37 -> 44 and world 176 at 6 mm,
    166, 168 and 174 at 2 cm more than twice worse (WPROC)."""
