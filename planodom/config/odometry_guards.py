"""Guards of the streaming odometry's deskewing policy (fields of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, kept in its own module so that
the policy's guards are documented together.
"""

from __future__ import annotations

from planodom.config.section import Section


class DeskewGuards(Section):
    """Guards of :mod:`planodom.odometry.deskew` (fields of ``odometry``)."""

    deskew_bounds_guard: bool = False
    """Streaming, pairwise pipelines: an epoch extracted again with its own twist
    (:mod:`planodom.odometry.deskew`, step 2) whose new step leaves the motion bounds the
    run assumes (``association.max_rotation_deg``, ``max_translation_m``, the rig's
    motion_bounds), where the estimate it was refined from stayed within them, lost track:
    the earlier estimate is kept, and the reference's planes from before that refresh
    (when the reference was extracted again for it) come back. Found on generalisation
    world 114 at 2 cm (2D rig, one sweep an epoch): the first step, measured OK without
    deskewing (yaw rate 35 deg/s, true 37), extracted both epochs again with its twist;
    two walls 3 m apart were then grouped into two planes tilted 23 deg, and the step
    became a 22 deg roll (degenerate), kept because the reference had been refreshed;
    deskewed with its 221 deg/s, the next steps were 6 and 12 deg off."""
