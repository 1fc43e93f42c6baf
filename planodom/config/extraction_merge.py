"""The 2D rig's coplanar groups merged (a field of ``extraction``).

A base of :class:`planodom.config.extraction.ExtractionConfig`, kept in its own module
(that one is near the layout limit).
"""

from __future__ import annotations

from planodom.config.extraction_noise import NoiseFields


class MergeFields(NoiseFields):
    """Whether the 2D rig's groups of one plane cut apart by the gap rule are joined
    (fields of ``extraction``)."""

    merge_coplanar_groups: bool = False
    """2D rig, deskewed epochs (not time windows): after the grouping and the groups'
    refits, two groups are one plane when each group's inliers lie within the member
    tolerance of the plane fit to both (RMS, the grouping's own rule for a trace joining a
    plane) and that plane's RMS residual is within the grouping's ``max_rms`` limit: the
    grouping's rules without the gap rule (``plane_gap_m``), which cuts a ground seen by a
    scanner pair ahead and one behind into two planes of one surface
    (:mod:`planodom.extraction.rig2d.coplanargroups`). Off by default (docs/RESULTS.md,
    GAPS6)."""
