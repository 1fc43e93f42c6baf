"""What the streaming odometry (:mod:`planodom.odometry.odometry`) keeps of an epoch."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planodom.angles import radians
from planodom.association import nonparallel_pairs
from planodom.config import AssociationConfig
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

    def has_pair(self, association: AssociationConfig) -> bool:
        """Whether its planes hold a non-parallel pair (normals more than
        ``association.parallel_angle_deg`` apart, either orientation): what the lenient
        association needs of a reference epoch. Two planes of one surface (a ground
        split in two groups) are two planes but no pair: against them every epoch is
        unresolved."""
        if len(self.planes) < 2:
            return False
        normals = self.plane_set.normals
        return bool(nonparallel_pairs(normals, radians(association.parallel_angle_deg))[1].any())
