"""Which first extractions of an epoch step 1 of the deskewing policy tries to better
(``odometry.untwisted_try``, :func:`planodom.odometry.deskew.register_deskewed`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from planodom.odometry.relative import Status

if TYPE_CHECKING:
    from planodom.odometry.deskew import EpochEstimate


def suspect(first: EpochEstimate, few: bool, previous_planes: int, mode: str) -> bool:
    """Whether ``first``, the epoch deskewed with the prediction, is tried again without a
    twist (and with the trend's or the held one): not OK, or ``few`` (far fewer planes
    than the ``previous_planes`` of the epoch before); with ``mode`` ``fewer_planes`` a
    degenerate ``first`` only when it has fewer planes than the epoch before (a degenerate
    epoch that lost no plane is degenerate by its geometry, not by its twist)."""
    status = first.relative.status
    if few or status is Status.UNRESOLVED:
        return True
    if status is Status.OK:
        return False
    return mode != "fewer_planes" or len(first.planes) < previous_planes
