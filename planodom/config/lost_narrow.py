"""Narrow seeds for an epoch the odometry leaves unresolved (a field of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.gate_release` is.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from planodom.config.section import Section


class LostNarrowConfig(Section):
    """``odometry.lost_narrow_seed_deg``: the narrow seeds tried where a step is lost;
    ``odometry.gap_end_rate``: the rate a step that ends a bridged stretch measures."""

    lost_narrow_seed_deg: float = Field(0.0, ge=0, le=90)
    """Pairwise pipelines (the 2D rig): an epoch whose kept estimate is unresolved is
    extracted once more with the same twist and ``extraction.narrow_seed_last_deg`` at
    least this (deg; :mod:`planodom.odometry.lost_narrow`), and that estimate is kept
    when it resolves the step (degenerate or ok). In a corridor turned near 45 deg to the
    heading each scanner pair of the isoclinal rig draws two lines crossing under
    ``min_cross_angle_deg`` on a wall, and the extraction keeps only the walls it crosses
    well: on the 2D-rig world 570 at 6 mm two parallel walls where the oracle fits six
    surfaces, 11 epochs bridged (docs/RESULTS.md, TILT16, GAP17). The narrow seeds found
    those walls (INDOOR3) but as a default cost the paper loop 4-16 % ATE and world 312
    its yaw (NARROW4), where every epoch resolves without them; here they are tried only
    where the step is lost anyway. 0: off (default); 0.5 is the narrow seeds' measured
    value (``max_seed_normal_error_deg``, INDOOR3), not tuned here. Judged with
    ``gap_end_rate: span`` (GAP17): world 570's gap* 11 -> 3 / 6 -> 3 (6 mm / 2 cm), the
    fresh worlds 660-678 unchanged but 678 (better), random-indoor better at every noise;
    the rule failed on random-outdoor at 2 cm (4.66 -> 9.24 m), which the span rate
    loses (this option alone: 4.55 m)."""

    gap_end_rate: Literal["step", "span"] = "step"
    """Pairwise pipelines: the own twist (the next epoch's deskewing twist, its prior and
    bridge) of a measured step whose reference is further back than the epoch before, a
    step that ends a bridged stretch. ``step`` (default): the step's, which holds the
    error of every bridged step before it, taken back at once: on the 2D-rig world 570 at
    6 mm with ``lost_narrow_seed_deg`` the step ending a 3-epoch stretch took back 2.1
    deg of bridged yaw, and the next epoch was bridged 2.5 deg off with that rate
    (docs/RESULTS.md, GAP17). ``span``: the twist of its measured relative pose over the
    epochs it spans (epochs at a constant period; with ``delta`` above 1, where every
    step spans several epochs, nothing changes). No threshold. Off: alone it doubles the
    built-in random-outdoor's ATE at 2 cm (4.66 -> 9.38 m, GAP17)."""
