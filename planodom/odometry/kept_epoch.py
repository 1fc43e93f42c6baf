"""What the streaming odometry (:mod:`planodom.odometry.odometry`) keeps of an epoch."""

from __future__ import annotations

from dataclasses import dataclass, field

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
    led: tuple[np.ndarray, float] | None = None  # its led twist's variance (planemap.lead_weights)
    # (plane set, plane count, parallel angle, answer) of the last has_pair: the odometry
    # asks it of its reference with every extraction of the next epoch
    _paired: tuple[PlaneSet, int, float, bool] | None = field(
        default=None, init=False, repr=False, compare=False
    )

    def has_pair(self, association: AssociationConfig) -> bool:
        """Whether its planes hold a non-parallel pair (normals more than
        ``association.parallel_angle_deg`` apart, either orientation): what the lenient
        association needs of a reference epoch. Two planes of one surface (a ground
        split in two groups) are two planes but no pair: against them every epoch is
        unresolved."""
        known, angle = self._paired, association.parallel_angle_deg
        if (
            known is not None
            and known[0] is self.plane_set
            and known[1:3] == (len(self.planes), angle)
        ):
            return known[3]
        paired = len(self.planes) >= 2 and bool(
            nonparallel_pairs(self.plane_set.normals, radians(angle))[1].any()
        )
        self._paired = (self.plane_set, len(self.planes), angle, paired)
        return paired
