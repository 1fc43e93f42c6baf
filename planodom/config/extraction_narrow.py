"""Narrow seeds taken after every other seed (a field of ``extraction``).

A base of :class:`planodom.config.extraction.ExtractionConfig`, kept in its own module
(that one is near the layout limit).
"""

from __future__ import annotations

from pydantic import Field

from planodom.config.extraction_merge import MergeFields


class NarrowSeedFields(MergeFields):
    """Whether the 2D rig's grouping tries narrow seeds on the traces its other seeds
    leave (a field of ``extraction``)."""

    narrow_seed_last_deg: float = Field(0.0, ge=0, le=90)
    """2D rig: two traces crossing under ``min_cross_angle_deg`` (down to 2 deg) seed a
    plane when its normal is predicted to this (deg), as with
    ``max_seed_normal_error_deg``, but such narrow seeds are taken only after every other
    seed (L seeds too), on the traces those left (:mod:`.rig2d.grouping`): every plane
    the wide seeds give is kept as it is, and a narrow seed never takes a trace from one. In a sharp turn of a corridor the walls lie near 45 deg to
    the heading, where each scanner pair of the isoclinal rig draws two long lines
    crossing at 4-9 deg on a wall and no wall is found (the built-in random-indoor at 2
    cm, epochs 490-500, deskewed with the truth: docs/RESULTS.md, INDOOR3); a thousand
    points on each of two 20 m lines fix its normal to about 0.1 deg. 0: off (default)."""
