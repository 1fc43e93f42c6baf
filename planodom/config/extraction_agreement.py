"""The RANSAC agreement check's planes without pixel normals (a field of ``extraction``).

A base of :class:`planodom.config.extraction.ExtractionConfig`, kept in its own module
(that one is near the layout limit).
"""

from __future__ import annotations

from typing import Literal

from planodom.config.section import Section


class AgreementFields(Section):
    """What the RANSAC planes' agreement check (``ransac_normal_agreement_deg``) does with
    a plane it cannot judge (fields of ``extraction``)."""

    ransac_unjudged: Literal["kept", "refused", "seed"] = "kept"
    """3D path, where ``ransac_normal_agreement_deg`` judges RANSAC planes: a plane with
    fewer than 3 inliers that have a pixel normal (:data:`planodom.extraction.lidar.
    agreement.MIN_JUDGED`). ``kept`` (default): nothing judges it. ``refused``: it is not a
    plane: the cuts through several facades' scan lines that escape the check are those
    whose points lie where the image gives no normal (facade edges, lone lines), and a true
    surface seen so sparsely gives the odometry little. Found on lidar world 161 at 2 cm
    (first 4 epochs, every extraction): 16 of 176 kept planes cut across facades (level,
    88-90 deg off their points' surfaces), 13 of them unjudged, against 1 true plane of
    the 160; they seeded the map and held the first steps' roll (0.17 deg off, later
    steps 0.001-0.005 deg). ``seed``: refused only while the streaming odometry registers
    its first two epochs (:mod:`planodom.odometry.seed_extraction`). Measured (odd worlds
    161-179, 150 epochs, the five runs where it acts; docs/RESULTS.md, LIDARSEED): rotation
    rms at 2 cm 0.49x (refused) and 0.76x (seed) in geometric mean, but ATE 1.29x and
    1.28x (1.18x, 1.22x at 6 mm): kept by default."""
