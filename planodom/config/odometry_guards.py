"""Guards of the streaming odometry's deskewing policy (fields of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, kept in its own module so that
the policy's guards are documented together.
"""

from __future__ import annotations

from typing import Literal

from planodom.config.bridge_normals import BridgeNormalsConfig
from planodom.config.deskew_pass_skip import DeskewPassSkipConfig
from planodom.config.gate_release import GateReleaseConfig
from planodom.config.lost_narrow import LostNarrowConfig
from planodom.config.map_lead_shrink import MapLeadShrinkConfig
from planodom.config.moment_refine import MomentRefineConfig
from planodom.config.narrow_rotation import NarrowRotationConfig
from planodom.config.plane_deskew_noise import PlaneDeskewNoiseConfig
from planodom.config.retry_status import RetryStatusConfig
from planodom.config.split_reference import SplitReferenceConfig
from planodom.config.stated_deskew_noise import StatedDeskewNoiseConfig
from planodom.config.untwisted_try import UntwistedTryConfig


class DeskewGuards(
    BridgeNormalsConfig,
    DeskewPassSkipConfig,
    GateReleaseConfig,
    LostNarrowConfig,
    MapLeadShrinkConfig,
    MomentRefineConfig,
    NarrowRotationConfig,
    PlaneDeskewNoiseConfig,
    RetryStatusConfig,
    SplitReferenceConfig,
    StatedDeskewNoiseConfig,
    UntwistedTryConfig,
):
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

    twist_sigma_fragments: bool = False
    """Streaming, ``twist_sigma: lost``: an extraction whose planes hold fewer distinct
    surfaces than planes (:func:`planodom.odometry.surfaces.distinct_surfaces`: a twist off
    the truth splits a wall into one plane per sweep) is lost too, and the widened one is
    then kept unless the first has a better status or as many distinct surfaces (the
    widened one as before only when consistent with the prediction). Off by default:
    found on 2D-rig world 166 at 6 mm (docs/RESULTS.md, DEGEN166), where a twist lagging
    a turn's exit split the walls and lost the ground while the plane count rose; not
    judged on other worlds."""

    deskew_rank: Literal["planes", "surfaces", "surfaces_first"] = "planes"
    """Streaming: how the deskewing policy ranks two extractions of an epoch
    (:mod:`planodom.odometry.surfaces`). ``planes``: status, then plane count, and a
    refinement is dropped only when its status is worse. ``surfaces``: status, then
    distinct surfaces (planes within ``association.normal_tol_deg`` and ``offset_tol_m``
    of each other count once: a wrong twist splits a wall into one plane per sweep), for
    both, a refinement dropped when that is worse. ``surfaces_first``: distinct surfaces
    among the first extractions only (predicted, held, none), refinements as ``planes``.
    Off (``planes``): both mixed on 2D-rig worlds 100-118, 140-158, 160-178 at 6 mm and
    2 cm (docs/RESULTS.md, REFINE)."""

    deskew_tie: Literal["first", "deskewed"] = "first"
    """Streaming, pairwise pipelines: which of two first extractions of an epoch that rank
    alike (``deskew_rank``) is kept. ``first``: the one tried first (after an unresolved
    epoch, the one extracted without deskewing; the held twist only when it ranks higher).
    ``deskewed``: the one deskewed with a twist (predicted, held, trend), by geometry: the
    scan's points were taken while the platform moved, and an extraction without a twist
    leaves that motion in them; when the ranks do not tell the two apart, the extraction
    that models the motion is kept. No threshold. Off by default: found on the built-in
    random-outdoor at sigma 0 (epoch 240, after unresolved 239: the undeskewed and the
    held-twist extractions both degenerate on the ground and one wall; the undeskewed one
    kept, its step 23 mdeg off, the held one's 0.05; docs/RESULTS.md, SIGMA0B)."""

    deskew_change_gate: bool = False
    """Streaming: extract an epoch again with its own twist (:mod:`planodom.odometry.
    deskew`, step 2) only where it differs from the twist used by more than the own
    twist's error explains (chi-square 95 %, :mod:`planodom.odometry.change_gate`), on
    top of ``deskew_rate_tolerance_deg_s`` / ``deskew_speed_tolerance_mps``. Off by
    default: on issue 11's 2D-rig worlds 0-18 (even, 150 epochs) it saves 6 % / 13 % of
    the extractions (2.46 -> 2.30 an epoch at 6 mm, 2.66 -> 2.31 at 2 cm) and 10-11 % of
    the CPU time, but at 2 cm the rotation gets worse on 9 of 10 worlds (median 0.146 ->
    0.178 deg rms, unresolved epochs 32 -> 42) and at 6 mm it is mixed (xy 1.95 -> 1.32
    cm median; world 6 0.24 -> 0.36 deg, world 0 ATE 0.29 -> 0.78 m): a twist within one
    step's error still smears a 2D scanner's sweep (docs/RESULTS.md, RIG2DPASS)."""

    deskew_rate_solve: Literal["fixed_point", "secant"] = "fixed_point"
    """Streaming, pairwise pipelines (the 2D rig's; the plane map keeps ``fixed_point``):
    how an epoch's angular rate is refined when it is extracted again with its own twist
    (:mod:`planodom.odometry.deskew`, step 2). ``fixed_point``: with its own
    rate each time; ``secant``: from the second refinement on, along the secant through
    the last two (rate used, own rate) towards the rate that is its own
    (:mod:`planodom.odometry.deskew_secant`): a degenerate step whose yaw rests on one far
    wall, which the deskewing tilts, diverges under the fixed point (issue 11's world 6 at
    6 mm, epoch 51: 12.36 -> 11.21 -> 8.04 deg/s for a true 12.74)."""

    start_refresh: bool = True
    """Streaming, pairwise pipelines, scans with point times: once a step is measured
    (status OK) after a start whose epochs were kept without deskewing (first steps
    degenerate or unresolved: no velocity measured), extract those epochs again with the
    measured epoch's twist, estimate the steps between them again with its constant-
    velocity prediction as prior, and chain the poses again
    (:mod:`planodom.odometry.start_epochs`; the first epochs' poses are then not causal).
    On by default, decided on worlds that did not choose it (a rule fixed before): on the
    even 2D-rig worlds 100-118 and 140-158, 150 epochs, it changes 8 of 40 runs (the rest
    bit-identical), ATE geometric-mean ratio 0.27 at 6 mm (2 of 2 better: world 108 0.335
    -> 0.039 m) and 0.54 at 2 cm (5 of 6 better: world 154 1.28 -> 0.10 m; worse world
    116 0.255 -> 0.280 m), unresolved epochs 18 -> 14. On worlds 0-38 it was mixed (ATE
    better on 7 of 10 changed, worse on 3: world 34 at 2 cm 0.177 -> 0.227 m); world 18's
    lap NEES5 207 -> 2.9 at 6 mm (docs/RESULTS.md, FIRSTEPOCH and STARTDEF)."""

    z_offset_measured_only: bool | None = None
    """Streaming, pairwise pipelines: the epoch's own twist takes the deskewing offset of
    its vertical velocity only when its step measured z (a near-level plane associated);
    else the vertical keeps the prediction's velocity (:mod:`planodom.odometry.
    vertical_offset`). Off: the offset is added to the prediction's vertical, and walks.
    None (default): on in the batch smoothing's odometry when it deskews with the coplanar
    twist (``smoothing.odometry_deskew_twist: coplanar``, :func:`planodom.smoothing.run.
    smoothing_config`), off elsewhere (``planodom run``). On 2D-rig world 142's lap (293
    epochs, 6 mm, coplanar twist) odometry ATE 5.54 -> 0.35 m, loop end's height 759 ->
    1.9 m off, batch + loops 73.4 -> 0.015 m; over ten held-out laps per noise (LAPZ in
    docs/RESULTS.md) batch + loops ATE geometric-mean ratio 0.35 at 6 mm, 0.94 at 2 cm,
    none worse by 5 %. Off for ``planodom run``: over 150 epochs at
    6 mm on worlds 0-18 it is mixed and small (HEIGHT; default twist: xy ATE geometric mean
    ratio 1.025, world 14 0.045 -> 0.054 m; quick start 3-D ATE 0.0707 -> 0.0728 m)."""

    refresh_keep_resolved: bool = False
    """Streaming, pairwise pipelines: like ``reference_refresh_guard`` but only for an
    estimate that the refresh left unresolved: when the next epoch's refinement against
    the reference extracted again with its twist is unresolved and the estimate before it
    was resolved, the reference's old planes are brought back and the resolved estimate
    kept (:mod:`planodom.odometry.deskew`, step 2). Off by default (REFKEEP in
    docs/RESULTS.md: PASSES2CM counted 14 of the 2 cm unresolved epochs on 2D-rig worlds
    160-178 made that way)."""

    refresh_keep_pair_held: bool = False
    """Streaming, pairwise pipelines: a reference extracted again while the epoch after an
    unresolved one is registered (its twist's linear velocity held over the unresolved
    epochs) keeps its planes when the new ones lose the non-parallel pair it had
    (:mod:`planodom.odometry.refresh_held`). Off: on 2D-rig world 192 at 2 cm it closes a
    6-epoch gap (ATE 2.34 -> 1.80 m) but on world 182 at 6 mm it keeps a phantom pair
    (0.93 -> 5.93 m; REFRESHHELD in docs/RESULTS.md)."""
