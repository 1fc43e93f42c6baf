"""An epoch's lidar segmentation reused when it is extracted again (a field of ``extraction``).

A base of :class:`planodom.config.extraction.ExtractionConfig`, kept in its own module
(that one is near the layout limit).
"""

from __future__ import annotations

from typing import Literal

from planodom.config.extraction_agreement import AgreementFields


class ReuseFields(AgreementFields):
    """Whether the 3D path segments a scan again when the streaming odometry extracts it
    again with another twist (fields of ``extraction``)."""

    segmentation_reuse: Literal["off", "near_twist"] = "off"
    """3D path with ``ring`` (range image or RANSAC loop): ``off`` (default): every
    extraction segments the scan anew. ``near_twist``: an extraction of the very scan
    extracted last (the same arrays, the same config) with a twist that moves no point
    by more than the member tolerance from where the last extraction's twist put it
    (to first order, ``max |t| (|dw| max |p| + |dv|)``) takes that extraction's candidate
    inlier sets, noise sigma and agreement pixel normals, and only fits them again to its
    own deskewed points (robust fits, plane builder): the streaming odometry extracts an
    epoch 1.07-1.7 times (its predicted twist, then its own), and the segmentation is
    about half of an indoor lidar extraction (:mod:`planodom.extraction.lidar.reuse`).
    Measured (docs/RESULTS.md, LIDARSPEED5): 0.83-0.96x the CPU time on 8 of 10 runs of
    the indoor worlds 153, 159, 163, 173, 179; on the held-out lidar worlds 163, 179 and
    181-199, 11 of 12 runs identical at 6 mm, at 2 cm ATE 1.07x in geometric mean (up
    to 1.25x): off by default."""
