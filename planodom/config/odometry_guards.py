"""Guards of the streaming odometry's deskewing policy (fields of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, kept in its own module so that
the policy's guards are documented together.
"""

from __future__ import annotations

from planodom.config.motion_model import MotionModelConfig


class DeskewGuards(MotionModelConfig):
    """Guards of :mod:`planodom.odometry.deskew` (fields of ``odometry``), and the motion
    model the prediction assumes (:class:`.motion_model.MotionModelConfig`)."""

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
    deskewed with its 221 deg/s, the next steps were 6 and 12 deg off. Off by default:
    measured (``experiment generalisation``, 2D rig, 150 epochs, 6 mm and 2 cm), it acts
    on world 114 at 2 cm only among worlds 100-118 (rotation 1.13 -> 0.32 deg rms, xy 4.85
    -> 4.93 cm, ATE 0.28 -> 0.43 m) and on world 8 only among worlds 0-18, whose true
    steps reach the default 1 m bound (5 m/s at 5 Hz): it then keeps wrong estimates (6 mm
    rotation 0.117 -> 0.160 deg, ATE 0.232 -> 0.197 m; 2 cm 0.140 -> 0.132 deg, 0.072 ->
    0.089 m); every other run is bit-identical. It is only as good as the bounds declared
    (docs/RESULTS.md, "New worlds 100-119")."""
    z_offset_measured_only: bool = False
    """Streaming, pairwise pipelines: the epoch's own twist takes the deskewing offset of
    its vertical velocity only when its step measured z (a near-level plane associated);
    else the vertical keeps the prediction's velocity (:mod:`planodom.odometry.
    vertical_offset`). Off: the offset is added to the prediction's vertical, and walks.
    On 2D-rig world 142's lap (293 epochs, 6 mm, smoothing's coplanar twist) odometry ATE
    5.54 -> 0.35 m, loop end's height 759 -> 1.9 m off, batch + loops 73.4 -> 0.015 m
    (world 20, 300 epochs: 0.027 -> 0.0085 m; world 0 the same). Off by default: over
    150 epochs at 6 mm on worlds 0-18 it is mixed and small (HEIGHT in
    docs/RESULTS.md; default twist: xy ATE geometric mean ratio 1.025, world 14 0.045 ->
    0.054 m; coplanar: 1.008, 3-D 0.96; quick start 3-D ATE 0.0707 -> 0.0728 m)."""
