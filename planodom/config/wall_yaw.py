"""Whether an unresolved step takes its yaw from walls of one direction (a field of
``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.odometry_guards` is.
"""

from __future__ import annotations

from planodom.config.section import Section


class WallYawConfig(Section):
    """Whether a step without an associated non-parallel pair measures its yaw."""

    wall_yaw: bool = False
    """Streaming, pairwise pipelines, a step with a prior and no associated non-parallel
    pair (unresolved): the planes SDA (``association.strict_normal_deg``) associates
    under the prior give its yaw, each by the angle between the horizontal parts of its
    two normals, weighed by that part's squared length over the normals' variances
    (:mod:`planodom.odometry.wall_yaw`): the two walls of a corridor, one direction,
    measure the heading though no pair measures the rotation. Roll, pitch and the
    translation along the walls keep the prior's; the translation across them is
    refined as a degenerate step's (``refinement``), and the step is degenerate.
    Off by default (no rule passed; docs/RESULTS.md, GAP334): found on 2D-rig world 334
    at 6 mm, a corridor after a turn where only the two walls are planes for 28 epochs
    and the bridged rate, the turn's last, puts 75 deg into the heading."""
