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

    retry_accepts: Literal["degenerate", "across_gap", "ok"] = "ok"
    """For the streaming odometry's steps (the smoothing's pairs, loop candidates and map
    matches keep ``degenerate``). ``ok`` (default): the prior-free retry replaces the
    solve under the prior only when it is OK (its rotation checked by the associated
    planes of three normal directions, its translation measured). ``across_gap``: so for
    a step whose reference is more than one epoch back (after bridged epochs, the bounds
    widened with the gap), as ``degenerate`` for a step over one epoch. ``degenerate``
    (the default until RETRY15): whenever it is degenerate. Without the prior's bounds the
    association spans every rotation up to ``association.max_rotation_deg`` times the gap
    (180 deg after nine epochs): a degenerate step's rotation then rests on one pair of
    planes whose dihedral angle another pair shares, and nothing else checks it. Found on
    the fresh 2D-rig world 480 at 2 cm (docs/RESULTS.md, RETRY15): after 12 bridged
    epochs, an epoch against a reference of two planes was kept degenerate with a yaw 82
    deg off the truth; its twist (5.2 rad/s) then deskewed the next epochs and, through
    ``start_refresh``, every epoch of the start (ATE 49.9 m; with ``ok`` 1.06 m,
    ``across_gap`` 9.3 m). Made the default by its rule, written first (fresh worlds
    500-518: no run changed; built-in scenes: no ATE worse, random-outdoor 2.73 -> 2.30 m
    at 6 mm and 5.11 -> 4.66 m at 2 cm, but its per-epoch rotation 0.153 -> 0.376 deg at
    6 mm and xy 7.9 -> 10.2 cm at 2 cm, and 3 / 7 more unresolved epochs). On the fresh
    worlds 520-558, run after the rule: ATE 0.9995 / 0.957 of the old default's
    (geometric mean, 6 mm / 2 cm), rotation 0.9995 / 1.006, unresolved 75 -> 73 / 95 ->
    104 (world 532 at 2 cm 7.70 -> 3.57 m; 540 at 2 cm rotation 0.88 -> 1.18 deg, 16 ->
    29 unresolved)."""

    gap_tilt: Literal["widened", "held"] = "widened"
    """What a gap of several epochs does to the association's bound on the relative tilt
    (the angle between the two epochs' base z axes, ``association.max_tilt_deg``).
    ``widened`` (default): nothing; the rotation bound ``max_rotation_deg`` times the gap
    (up to 180 deg) bounds tilt as it bounds yaw. ``held``: the tilt stays bounded by one
    epoch's ``max_rotation_deg`` whatever the gap, while yaw widens with it: the tilt of
    a wheeled vehicle's base against gravity is bounded by the ground it stands on, so
    its change between two epochs does not grow with the time between them as its
    heading's may. ``widened`` unless set here, ``held`` on a vehicle (``platform``).
    Found on the 2D-rig world 570 at 6 mm (docs/RESULTS.md, TILT16): after 11 bridged
    epochs the prior-free retry kept an OK step 46 deg off in tilt (roll -21, pitch 42
    deg) against a reference of four planes, ATE 14.1 m (``held``: 0.021 m). Its rule,
    written first: fresh 2D-rig worlds 580-598, the built-in scenes and both identity
    runs unchanged bit for bit (it acts only where a gap's retry finds a tilted alias)."""
