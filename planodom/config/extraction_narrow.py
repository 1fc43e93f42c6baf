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
    the wide seeds give is kept as it is, and a narrow seed never takes a trace from one.
    In a sharp turn of a corridor the walls lie near 45 deg to the heading, where each
    scanner pair of the isoclinal rig draws two long lines crossing at 4-9 deg on a wall
    and no wall is found (the built-in random-indoor at 2 cm, epochs 490-500, deskewed
    with the truth). 0: off (default), measured with 0.5 (docs/RESULTS.md, INDOOR3): its
    rule passes on the 2D-rig worlds 240-258 (ATE geometric mean 0.83x / 0.73x at 6 mm /
    2 cm, unresolved 25 -> 16 / 19 -> 16) and random-indoor goes 6.00 -> 1.00 m at 2 cm,
    but the paper loop's ATE grows by 4-16 % (2 cm: 0.165 -> 0.182 m)."""
