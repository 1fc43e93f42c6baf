"""The 2D rig's gap bridged where one side's plane predicts the other (a field of
``extraction``).

A base of :class:`planodom.config.extraction.ExtractionConfig`, kept in its own module
(that one is near the layout limit).
"""

from __future__ import annotations

from typing import Literal

from planodom.config.extraction_narrow import NarrowSeedFields


class GapBridgeFields(NarrowSeedFields):
    """Whether the 2D rig's grouping bridges the gap rule where the geometry tells (a
    field of ``extraction``)."""

    gap_bridge: Literal["off", "predicted"] = "off"
    """2D rig: a growing plane whose seed's second trace lies beyond ``plane_gap_m`` of
    the first (the gap rule cuts it, and the seed dies) keeps it with its connected
    piece when the plane fit to one piece alone predicts the other's: its offset at the
    other piece's centroid known to a third of the member tolerance (from the piece's
    scatter, the noise sigma and the lever arm) and every trace of the other piece
    within the member tolerance of it (:mod:`planodom.extraction.rig2d.bridge`). Two
    traces alone never bridge (their common normal is too uncertain 20-40 m away); one
    side must hold traces spread across. Indoors a floor or ceiling is seen as short
    traces 15-30 m ahead and behind, 20-40 m apart (the built-in random-indoor's turn at
    2 cm, docs/RESULTS.md, INDOOR3). ``off``: the gap rule alone (default);
    ``predicted``: bridged as above. Off by default, measured (docs/RESULTS.md, GAPRULE):
    on the 2D-rig worlds 280-298 ATE geometric mean 0.67x / 0.85x at 6 mm / 2 cm,
    unresolved 25 -> 16 / 19 -> 17 (world 296 5.0 -> 0.06 m at 6 mm), and 10 of the 15
    built-in rows better (random-indoor 2 cm 6.00 -> 4.94 m), but random-outdoor at
    sigma 0 0.061 -> 0.146 m ATE xy, which its rule forbids."""
