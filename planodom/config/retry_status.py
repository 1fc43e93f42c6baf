"""Which status a prior-free retry may be kept with (a field of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.odometry_guards` is.
"""

from __future__ import annotations

from typing import Literal

from planodom.config.section import Section


class RetryStatusConfig(Section):
    """The status a solve without the prior's bounds must reach to replace the solve under
    them (``odometry.retry_without_prior``)."""

    retry_accepts: Literal["degenerate", "across_gap", "ok"] = "degenerate"
    """``ok``: the prior-free retry replaces the solve under the prior only when it is OK
    (its rotation checked by the associated planes of three normal directions, its
    translation measured); ``across_gap``: so for a step whose reference is more than one
    epoch back (after bridged epochs, the bounds widened with the gap), as ``degenerate``
    for a step over one epoch; ``degenerate`` (default): whenever it is degenerate. Without
    the prior's bounds the association spans every rotation up to
    ``association.max_rotation_deg`` times the gap (180 deg after nine epochs): a
    degenerate step's rotation then rests on one pair of planes whose dihedral angle
    another pair shares, and nothing else checks it. Found on the fresh 2D-rig world 480 at
    2 cm (docs/RESULTS.md, RETRY15): after 12 bridged epochs, an epoch against a reference
    of two planes was kept degenerate with a yaw 82 deg off the truth; its twist (5.2
    rad/s) then deskewed the next epochs and, through ``start_refresh``, every epoch of
    the start (ATE 49.9 m)."""
