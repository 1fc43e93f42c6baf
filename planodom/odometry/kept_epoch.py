"""What the streaming odometry (:mod:`planodom.odometry.odometry`) keeps of an epoch."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planodom.geometry import Plane
from planodom.planes import PlaneSet
from planodom.scan import Scan


@dataclass
class KeptEpoch:
    """What the odometry keeps of a registered epoch: its planes (and their arrays), and,
    for re-extraction, its scan and the twist it was deskewed with (None: not deskewed)."""

    index: int
    planes: list[Plane]
    plane_set: PlaneSet
    scan: Scan | None = None
    twist: np.ndarray | None = None
    kept: bool = False  # its planes were brought back after extracting it again made it worse
