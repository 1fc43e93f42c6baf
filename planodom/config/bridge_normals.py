"""Whether a bridged step's rotation is corrected by the normals it shares with its
reference (a field of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.odometry_guards` is.
"""

from __future__ import annotations

from typing import Literal

from planodom.config.section import Section


class BridgeNormalsConfig(Section):
    """Whether an unresolved step's bridge takes the rotation its shared normals give."""

    bridge_normals: Literal[False, True, "weighed"] = False
    """Streaming, pairwise pipelines: an unresolved step (no associated non-parallel
    pair), bridged by constant velocity, has its rotation corrected by the planes it
    shares with its reference: SDA associates them under the bridge (normals within
    ``association.prior_rotation_deg + strict_normal_deg``, then within
    ``strict_normal_deg`` of the corrected rotation), and the rotation that best turns
    the current normals onto the reference's, weighed by their covariances, is applied
    in the directions they observe (:mod:`planodom.odometry.bridge_normals`): the two
    walls of a corridor, one direction, measure the heading and the roll about the
    corridor though no pair measures the whole rotation. The translation and the step's
    status stay the bridge's. No threshold of its own: the gates are the association's.
    Found on 2D-rig world 334 at 6 mm, a corridor after a turn where only its two walls
    are planes for 28 epochs and the rate bridged, the turn's last, put 75 deg into the
    heading (ATE 12.3 -> 3.0 m with it, 2 cm 3.9 -> 2.4 m). Off by default: its rule
    failed (docs/RESULTS.md, GAP334): on the fresh 2D-rig worlds 340-358 the ATE
    geometric-mean ratio is 1.048 at 6 mm (0.995 at 2 cm); random-outdoor at sigma 0
    goes 0.061 -> 0.457 m (its bridged steps 568-573 take 0.01-0.04 deg more yaw error
    from their planes' model errors) and random at 6 mm 0.46 -> 0.61 m, while
    random-indoor goes 2.40 -> 0.72 m at 6 mm and 6.00 -> 2.09 m at 2 cm.

    ``weighed``: the same correction weighed against the bridge's own rotation error
    (:meth:`planodom.odometry.twist_sigma.TwistUncertainty.bridged_rotation_sigma`, the
    held rate's sigma summed over the bridged steps), a combined estimate (module
    :mod:`planodom.odometry.bridge_normals`). Off too: its rule failed (docs/RESULTS.md,
    GAPW): on the fresh 2D-rig worlds 360-378 the ATE ratios are 0.988 / 0.995 (6 mm / 2
    cm) but the unresolved epochs grow 13 -> 17 at 2 cm, and random-outdoor at sigma 0 goes
    0.061 -> 0.457 m, random at 6 mm 0.46 -> 0.54 m; the bridge's sigma is large next to
    the normals', so it acts as ``true`` does (within 0.011 m on those worlds)."""
