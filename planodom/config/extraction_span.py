"""Which planes the 2D rig's seed may carry across the gap rule (a field of ``extraction``).

A base of :class:`planodom.config.extraction.ExtractionConfig`, kept in its own module
(that one is near the layout limit).
"""

from __future__ import annotations

from pydantic import Field

from planodom.config.extraction_bridge import GapBridgeFields


class SpanFields(GapBridgeFields):
    """The tilt of the planes ``seed_spans_gap`` keeps whole (a field of ``extraction``)."""

    seed_spans_gap_max_tilt_deg: float = Field(90.0, gt=0, le=90)
    """2D rig, with ``seed_spans_gap``: a seed pair keeps the traces connected to either
    of its traces only when its plane's normal is within this angle (deg) of the base
    frame's z axis, a floor, a ground or a ceiling; steeper planes keep the gap rule.
    90 (default): any plane. The case ``seed_spans_gap`` was built for is a floor seen by
    one scanner ahead and one behind (the fresh world 662's corridor, 37 epochs bridged
    where the oracle measures, docs/RESULTS.md SPAN17); the case it loses is a wall: the
    urban canyon at 2 cm, where coplanar facades far apart along a street are joined
    (rotation 0.038 -> 0.301 deg). A vehicle's floor is one plane under it, a street's
    facades need not be. 30 separates level from steep planes with room for slopes and
    the vehicle's own tilt (a class boundary, not tuned to a world). Measured with 30
    (seen cases, no rule): the canyon's rotation kept (0.0382 -> 0.0385 deg) but its
    ATE still worse (0.41 -> 0.50 m), random-outdoor at 2 cm 4.66 -> 7.09 m, world 662
    as with every plane."""
