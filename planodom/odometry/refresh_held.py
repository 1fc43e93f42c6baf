"""A reference refresh after an unresolved epoch never takes the reference's pair away.

The streaming odometry extracts its reference epoch again with the twist its next epoch is
refined with (:mod:`planodom.odometry.deskew`, step 2). After an unresolved epoch that
twist's linear velocity is held over the unresolved epochs (``bridge_twist``), never
measured by a step since, and its angular rate is at best the epoch's own degenerate
estimate: on 2D-rig world 192 at 2 cm such a refresh turned reference epoch 79's
[ground, wall] into [ground, ground], a 6-epoch gap. With
``odometry.refresh_keep_pair_held`` such a refresh is undone when the reference had a
non-parallel pair (:meth:`.kept_epoch.KeptEpoch.has_pair`) and lost it. Refreshes after a
resolved epoch are left alone. Measured (REFRESHHELD in docs/RESULTS.md) it does not
spare world 182 at 6 mm, whose phantom pair GAPS5's unrestricted undo kept: that refresh
also follows an unresolved epoch, with a degenerate step's angular rate and a held
linear velocity, as on 192.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from planodom.odometry.odometry import PlaneOdometry

#: ``refresh(twist) -> bool``: extract the reference again with ``twist`` (rad/s, m/s, (6,));
#: whether it did.
Refresher = Callable[[np.ndarray], bool]


def held_refresh(odometry: PlaneOdometry, unresolved: bool) -> Refresher:
    """``odometry``'s reference refresh for the epoch being registered; when the epoch
    before was ``unresolved`` and ``odometry.refresh_keep_pair_held`` is on, a refresh that
    leaves the reference no non-parallel pair where it had one is undone (its planes come
    back, it is not extracted again) and reported as not done."""
    refresh = odometry._refresh_reference
    if not (unresolved and odometry.config.odometry.refresh_keep_pair_held):
        return refresh
    association = odometry.config.association

    def kept_pair(twist: np.ndarray) -> bool:
        ref = odometry._reference()
        paired = ref.has_pair(association)
        if not refresh(twist):
            return False
        if paired and not ref.has_pair(association):
            odometry._restore_reference()
            return False
        return True

    return kept_pair
