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
    """Streaming, pairwise pipelines: an unresolved step (no associated non-parallel
    pair), bridged by constant velocity, takes its yaw from the walls it shares with its
    reference: SDA associates the planes under the bridge (normals within
    ``association.prior_rotation_deg + strict_normal_deg``, then within
    ``strict_normal_deg`` of the corrected rotation), and each wall's normal gives the
    angle about the vertical, weighed by its horizontal part squared over the normals'
    variances (:mod:`planodom.odometry.wall_yaw`): the two walls of a corridor, one
    direction, measure the heading though no pair measures the rotation. Roll, pitch,
    the translation and the step's status stay the bridge's. Off by default (no rule
    passed it; docs/RESULTS.md, GAP334); found on 2D-rig world 334 at 6 mm, a corridor
    after a turn where only its two walls are planes for 28 epochs and the rate bridged,
    the turn's last, put 75 deg into the heading. No threshold of its own: the gates
    are the association's."""
