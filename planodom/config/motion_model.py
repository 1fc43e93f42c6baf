"""The motion model of the streaming odometry's prediction (a field of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.odometry_guards` is.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from planodom.config.association import Positive
from planodom.config.section import Section


class MotionModelConfig(Section):
    """What the predicted twist assumes of the platform (field of ``odometry``)."""

    motion_model: Literal["constant_velocity", "nonholonomic", "nonholonomic_degenerate"] = (
        "constant_velocity"
    )
    """Pairwise pipelines (the 2D rig; the plane map has its own motion model): the twist
    predicted for the next epoch (deskewing, prior, bridge, and, with
    ``refine_unmeasured: prediction``, what a degenerate step's unmeasured direction
    keeps). ``constant_velocity``: the recent twist as measured (the step's angular rate,
    the median linear velocity of the recent measured steps); ``nonholonomic``: the same
    without its lateral (y) component, as a wheeled vehicle whose base frame is its own
    (x forward) moves (:func:`planodom.odometry.motion_model.predicted_motion`; the
    vertical component is kept: the ground measures it, and a base that pitches moves
    along its z); ``nonholonomic_degenerate``: that only after a step that was not "ok"
    (degenerate or unresolved), where the prediction fills what the planes did not
    measure. Both also solve a degenerate step's unmeasured direction from the planes and
    the vehicle's constraint (``nonholonomic_sigma_m``). Never for a hand-held sensor.
    Off by default: 2D-rig worlds 0-18 and 100-118, 150 epochs (``nonholonomic_degenerate``,
    ATE geometric mean of the ratios 0.76 at 6 mm, 0.60 at 2 cm; xy per epoch better on
    12 / 13 of 20 worlds, worse on 1 / 0), but world 6 0.46 -> 2.2 m (6 mm) and world 2 at
    2 cm 1.27 -> 3.7 m, their rotation in a tightening turn (docs/RESULTS.md,
    "Non-holonomic constraint")."""

    nonholonomic_sigma_m: Positive = 0.005
    """With a non-holonomic ``motion_model``: the sigma, m, of a step's lateral
    displacement off a vehicle's arc (no lateral velocity at the base origin over the
    step), with which a degenerate step's translation is solved from its planes and
    that constraint (:mod:`planodom.odometry.nonholonomic`): a wall oblique to the track
    then gives the along-track step instead of the prediction. The simulator's vehicles
    depart from the arc by 0.18 mm rms, 1.3 mm at most per step (2D-rig worlds 0-18,
    100-118); 5 mm leaves room for the step's rotation error. A real vehicle slips more:
    about its slip angle times its speed times the epoch interval."""

    unobserved_vertical: Literal["held", "zero", "measured"] = "held"
    """Pairwise pipelines: the vertical velocity a step whose vertical translation was not
    observed (no ground-like plane associated, ``estimate_z``) passes to the predicted
    twist. ``held``: its own, which is the prediction's it started from (the solver keeps
    the prior's z), so a vertical velocity that no step measured is carried on;
    ``zero``: none, the body frame's vertical velocity of a base that moves along its own
    axis; ``measured``: the median of the recent measured steps' (those that observed z,
    or counted as their median), zero where there are none (after an unresolved epoch),
    so a bridge's vertical velocity is never held. Built for the seen 2D-rig lap 366 at
    6 mm (docs/RESULTS.md, VERTICAL14): a wrong step (108 deg) and its bridge left a
    vertical velocity of -21 m/s in the prediction; deskewed with it the floor was no
    plane, so no later step observed z, and the held value was carried over the last 716
    epochs (-1.39 m a step, "ok" throughout; the 5-DoF errors do not show it, the lap's
    ATE does: 389 m)."""

    bridge_rate: Literal["last", "trend", "median", "robust"] = "last"
    """Streaming, pairwise pipelines: the angular rate an unresolved epoch is bridged with
    (and the epoch after it is tried deskewed with, the held twist): ``last``, the
    prediction's (the last measured step's); ``trend``: along the straight-line trend of
    the recent epochs that measured it (:mod:`planodom.odometry.bridge_trend`), for a turn
    that tightens steadily, where the held rate lags (issue 11's world 6 at 6 mm: 8.2
    deg/s held for a true 13.7-15.9); ``median``: the component-wise median of the angular
    rates of the last ``bridge_median_steps`` steps that measured it, so one degenerate
    step's wrong rate is not held over a whole gap (issue 11's random-outdoor at 2 cm: 11
    epochs bridged with one step's rate 2 deg off; docs/RESULTS.md, RANGEOUT and
    BRIDGEMED); ``robust``: a Kalman filter's rate at the last of the recent measured
    steps (a random walk, its variance from how the steps before the last moved, each
    step weighed by its stated covariance), so a precise step at a turn's onset is kept
    and a poor one that departs from steady neighbours is not
    (:mod:`planodom.odometry.bridge_robust`, BRIDGE3). The velocity stays the
    prediction's."""

    bridge_median_steps: Annotated[int, Field(ge=1, le=50)] = 5
    """With ``bridge_rate: median``: how many of the last measured steps' angular rates
    the median is taken over (at most ``velocity_window`` are kept; 5 is RANGEOUT's
    what-if, not tuned)."""

    deskew_rate_lead: Literal["off", "yaw", "yaw_split", "rate"] = "off"
    """Streaming, pairwise pipelines: the own twist an epoch is extracted again with
    (``deskew_iterations``), the mean over its step, is centred half an epoch plus its
    points' mean time before them and lags a turn whose rate changes (the 2D rig's world
    166: 1.1-1.35 deg/s in yaw, its walls split one plane per sweep). ``yaw``: its yaw rate
    led to the points' mean time along its change since the previous epoch's own, both
    steps OK (:mod:`planodom.odometry.centred_twist`); ``rate``: the roll and pitch rates too
    (measured far less well by one step); ``yaw_split``: the yaw rate of an extraction
    that splits a wall only; ``off``: as it is (docs/RESULTS.md, TURNLAG)."""

    turn_trend_retry: bool = False
    """Streaming, pairwise pipelines (the 2D rig's): when the epoch deskewed with the
    prediction (the last step's rate, 1.5 epochs before its points) is suspect (not OK, or
    far fewer planes than the epoch before), it is tried first, before without deskewing,
    with the yaw rate along the trend of the recent measured rates extrapolated to its
    points' mean time, where that differs from the prediction's by more than
    ``deskew_rate_tolerance_deg_s``; kept when it ranks higher (``deskew_rank``)
    (:mod:`planodom.odometry.turn_trend`; a turn that tightens, the 2D-rig world 244 at 6
    mm: 3.8 deg/s predicted low, its epoch degenerate; docs/RESULTS.md, TURN244)."""

    turn_trend_rates: Annotated[int, Field(ge=3, le=20)] = 3
    """With ``turn_trend_retry``: over how many of the last measured rates the trend is
    fitted (at most ``velocity_window`` are kept). A turn that tightens ever faster (the
    2D-rig world 244: 1.6, 1.7, 2.0, 2.2 deg/s more each epoch) is followed by a short
    line; a longer one averages more noise."""

    turn_trend_keep: Literal["rank", "status"] = "rank"
    """With ``turn_trend_retry``: when the trend's extraction is kept over the
    prediction's: ``rank``, when it ranks higher (``deskew_rank``: status, then planes);
    ``status``, only when its step's status is better (a degenerate step's plane count
    picked the trend where it was no nearer the truth: the 2D-rig world 282 at 2 cm, a
    steady 4 deg/s turn, the trend kept at 5 epochs and nearer the true rate at 11 of 25;
    docs/RESULTS.md, TURN244)."""

    bridge_trend_epochs: Annotated[int, Field(ge=1, le=20)] = 3
    """With ``bridge_rate: trend``: how many epochs past the last measured rate the trend
    may run; further bridged epochs keep the rate it reached there."""

    bridge_ends: Literal["held", "interpolated"] = "held"
    """Any pipeline: the steps of a stretch of unresolved epochs in the run's poses.
    ``held``: as the streaming odometry bridged them (``bridge_rate``). ``interpolated``:
    after the run, where the stretch ends with a measured step (ok or degenerate, between
    consecutive epochs, as is the step into the epoch before it), each bridged step is
    made again with the twist interpolated linearly in time between those two measured
    steps, and the poses are chained through them (:mod:`planodom.odometry.bridge_ends`;
    the streaming estimates and the measured steps are unchanged). No threshold. Off by
    default: found on the built-in random-outdoor at sigma = 0, where the stretch 563-573
    (a turn whose rate climbs 5.72 -> 5.99 deg/s) held step 562's rate (docs/RESULTS.md,
    SIGMA0), and its rule's figures are there."""

    degenerate_ends: Literal["kept", "interpolated"] = "kept"
    """Any pipeline: a stretch of degenerate steps in the run's poses. ``kept``: as
    estimated. ``interpolated``: after the run (its deskewing passes), where the stretch
    has an OK step on both sides, each degenerate step's translation along its unmeasured
    direction (its x, y covariance's larger axis) is made again from the velocity
    interpolated linearly in time between the median velocities of up to
    ``velocity_window`` OK steps at each end, and the poses are chained through them
    (:mod:`planodom.odometry.degenerate_ends`; rotations and measured directions kept).
    Off by default: found on the built-in urban canyon at 6 mm with one deskewing pass
    and the moments (its degenerate steps' weak along-track translation 13.7 mm rms,
    ATE xy 0.089 -> 0.031 m); without the passes the OK steps at the ends are too noisy
    (5.8 mm rms there, ATE 0.072 -> 0.077 m). Docs/RESULTS.md, P1MP14."""

    pairwise_deskew: Literal["streaming", "passes_moments"] = "streaming"
    """Runs over a sequence (``run_odometry``): ``passes_moments``, where a pairwise
    pipeline runs (the 2D rig), ``deskew_passes: 1``, ``refinement: moments``,
    ``moment_gate_chi2: 20.5``, ``moment_passes: deskew_passes`` and ``degenerate_ends:
    interpolated``, each unless the config sets it (:mod:`planodom.odometry.
    pairwise_deskew`); the plane map (the lidars) keeps its fields. ``streaming``: the
    fields as set. Off by default: the candidate of docs/RESULTS.md P1MP14, decided by
    the lead's rule there; making it the 2D rig's default is this one value."""

    rate_prediction: Literal["constant", "autoregressive", "selected"] = "constant"
    """Streaming, pairwise pipelines (the 2D rig's): the angular rate predicted for the next
    epoch (its deskewing, prior and bridge). ``constant``: the last step's;
    ``autoregressive``: each component along an autoregression of ``rate_prediction_order``
    fitted online to the last ``rate_prediction_window`` steps that measured the rate one
    after the other (:mod:`planodom.odometry.rate_prediction`; a generic linear predictor,
    no model of the vehicle); ``selected``: that only where it predicted the last
    ``rate_prediction_check`` measured rates better than the constant rate did. Off by
    default: on the measured rates of 2D-rig worlds 0-18 and 160-178 (150 epochs) it is
    off the epoch's true rate by 0.37-0.74x the constant rate's error (median), and the
    first refinement is skipped more often (extractions an epoch 2.46 -> 1.97 at 6 mm,
    2.69 -> 2.43 at 2 cm, worlds 0-18), but the runs lose: ATE geometric-mean ratio 1.31
    / 1.22 (6 mm / 2 cm) on worlds 0-18, world 6 0.51 -> 1.56 m; a wrong rate of a
    degenerate step is extrapolated (docs/RESULTS.md, PREDICT)."""

    rate_prediction_order: Annotated[int, Field(ge=1, le=8)] = 4
    """With ``rate_prediction: autoregressive``: the autoregression's order (lags)."""

    rate_prediction_window: Annotated[int, Field(ge=8, le=400)] = 60
    """With ``rate_prediction: autoregressive``: how many measured steps it is fitted to
    (it predicts once it has twice as many equations as terms, the last rate before)."""

    rate_prediction_check: Annotated[int, Field(ge=1, le=100)] = 10
    """With ``rate_prediction: selected``: on how many of the last measured rates the
    autoregression must have predicted better than the constant rate (summed squared
    error) to be used."""

    rate_prediction_fit: Literal["measured", "ok_filled", "ok_runs"] = "measured"
    """With ``rate_prediction`` not ``constant``: which steps' rates the autoregression is
    fitted to. ``measured``: every step that measured its rotation; ``ok_filled`` and
    ``ok_runs``: only steps of status ok with the whole rotation observed (a degenerate
    step's rate can be wrong by ten degrees a second); any other step is replaced in the
    run by the rate predicted for it (``ok_filled``, the prediction after it the fit's) or
    restarts the run (``ok_runs``, the prediction after it the constant rate's). Both lose
    over the worlds too (ATE ratio 1.05-1.47 at 6 mm on 2D-rig worlds 0-18 and 160-178,
    docs/RESULTS.md, PREDICT2)."""

    rate_prediction_bound: bool = False
    """With ``rate_prediction`` not ``constant``: limit the predicted change from the last
    fitted rate, per component, to the largest change between consecutive rates of the
    window (no better: docs/RESULTS.md, PREDICT2)."""

    rate_prediction_use: Literal["all", "first_deskew"] = "all"
    """With ``rate_prediction`` not ``constant``: where the predicted rate is used.
    ``all``: the twist predicted for the next epoch (its deskewing, prior, bridge and
    gates); ``first_deskew``: only the twist the epoch is first deskewed with, the prior,
    the bridge, the gates and the retries keeping the constant rate. Off by default: 2D-rig
    worlds 0-18 at 6 mm, extractions an epoch 2.46 -> 1.91, but ATE ratio 1.05 / 1.14 (6 mm /
    2 cm), and on 160-178 world 166 0.48 -> 1.92 m (docs/RESULTS.md, PREDICT3)."""

    twist_blend: Literal["off", "rate", "degenerate"] = "off"
    """Streaming, pairwise pipelines (the 2D rig's): how a step's own angular rate enters
    the twist its epoch is deskewed with again and the one predicted for the next.
    ``off``: it replaces the prediction (beyond ``deskew_rate_tolerance_deg_s``);
    ``rate``: a Kalman update per axis, weighed against the prediction by the step's
    rotation covariance and the prediction's (the previous posterior plus one epoch of
    the rate's measured change), so an axis a degenerate step hardly measures (roll and
    pitch from walls alone) keeps the prediction (:mod:`planodom.odometry.twist_blend`);
    ``degenerate``: that for steps that are not OK only, an OK step's rate replacing the
    prediction as with ``off``. Off by default (docs/RESULTS.md, TWISTBLEND)."""

    platform: Literal["auto", "vehicle", "handheld", "unknown"] = "auto"
    """What carries the sensors. ``auto``: what the dataset declares (``rig.yaml``'s
    ``platform``, :data:`planodom.rig.PLATFORMS`: the simulator's built-in scenes and
    random worlds write "vehicle", a hand-held walk "handheld"; the KITTI readers
    "vehicle"), else ``unknown``; a bag or a folder of scans declares nothing. ``vehicle``
    switches on the options that assume a wheeled vehicle whose base frame is its own (x
    forward, z up) and that passed their rules: ``start_vehicle_twist`` and ``gap_tilt:
    held`` (TILT16). An option the
    config sets explicitly keeps its value (:mod:`planodom.odometry.platform`).
    ``handheld`` and ``unknown``: none of them (the behaviour before this field); both
    override what the dataset declares. The resolved configuration a run writes names
    the platform it used. Evidence for ``start_vehicle_twist`` (docs/RESULTS.md, GAPS6):
    2D-rig world 190 at 2 cm, its start's gap 8 -> 0 epochs, ATE 11.1 -> 5.3 m; all 20
    runs of worlds 160-178 (6 mm, 2 cm, 150 epochs; a rule written first) and the 15
    built-in scene rows identical; 1 of the 60 runs of 140-198 changed, for the better.
    Never measured on hand-held sensors, hence not for ``unknown``."""

    start_vehicle_twist: bool = False
    """Pairwise pipelines, a vehicle (never a hand-held sensor): at the start, while no
    step has measured an angular rate, an epoch whose own step is degenerate but reported
    unresolved by ``degenerate_gate`` (its rate against the prediction of a start that
    measured none) is extracted again, with its reference, deskewed with a vehicle's twist
    made of that step: its yaw rate (about the base z) and its velocity along the base x,
    the roll and pitch rates and the lateral and vertical velocity zero (a vehicle's are
    small; a degenerate step's roll and pitch come from a wall the undeskewed extraction
    tilts). Repeated with the new step's own (``deskew_iterations`` rounds) and kept only
    when the step is OK; else the reference's planes come back
    (:mod:`planodom.odometry.vehicle_start`). Off by default, on with ``platform``
    vehicle unless set here (docs/RESULTS.md, GAPS6 and PLATFORM)."""

    start_twist_search: bool = False
    """Pairwise pipelines, a vehicle: at the start, while no step has measured an angular
    rate (the first 20 epochs at most), an epoch whose step is unresolved (no twist from
    it for ``start_vehicle_twist``) is extracted again, with its reference, deskewed with
    each of a vehicle's yaw rates (10 to 60 deg/s, both signs, 10 deg/s apart: a car's
    turns, not taken from any world) and estimated again; of the OK steps, the one whose
    own yaw rate is nearest its deskewing rate is refined with its own yaw rate and
    forward velocity (``deskew_iterations`` rounds, each kept while OK); with none OK
    the reference's planes come back (:mod:`planodom.odometry.start_search`). Off by
    default: built for 2D-rig world 292 at 6 mm, a start in a 36 deg/s turn
    (docs/RESULTS.md, GAP292 and START292)."""

    start_search_speed: Literal["candidate", "measured"] = "candidate"
    """With ``start_twist_search``, once a step of a searched start is measured (status
    OK; ``start_refresh`` on): the speed of the start's steps that measure only rotation
    (degenerate: one wall along the track leaves the speed to the prior).
    ``candidate``: ``start_refresh`` extracts again only the start's epochs not extracted
    again since they were registered, so the searched epochs, and those deskewed with the
    predictions that followed, keep the searched candidate's guessed speed (2D-rig world
    356 at 2 cm: steps 1-8 within 0.15 deg of yaw, 67-71 cm off in xy each).
    ``measured``: when the search gave the start's step, every epoch of the start is
    extracted again with the measured step's velocity (and its degenerate step's rate)
    and its steps estimated again with that velocity as their prior
    (:mod:`planodom.odometry.start_epochs`). No threshold (docs/RESULTS.md, START356)."""

    start_redeskew: Literal["off", "converged"] = "off"
    """Pairwise pipelines: the start's epochs deskewed again once the measured velocity has
    converged. The first epochs are deskewed with the twist the first one or two steps
    measured, each step's noise in it (2D-rig lap 342 at 6 mm: first step 3.27 m/s for a
    true 3.45, epoch 0's planes 4.3 cm off, and every loop factor closes on epoch 0).
    ``converged``: the own velocities of the first OK steps are averaged, weighed by their
    covariances, until the mean moves by less than its own standard error (or a step
    disagrees with it: the motion changed); then epochs 0 .. K (the last averaged step)
    are extracted again with that mean velocity (each with its step's own angular rate)
    and their steps estimated again, a new step kept only when its status is no worse and
    its rotation agrees with the old one within their covariances
    (:mod:`planodom.odometry.start_converged`). Off by default (docs/RESULTS.md, START3)."""

    start_redeskew_guard: Literal["step", "all"] = "step"
    """With ``start_redeskew: converged``, what a step refused by its guard (status
    worse, or its rotation outside the two estimates' covariances) undoes: ``step``, that
    step alone (its first estimate kept, marked superseded; its epochs keep the planes
    extracted again); ``all``: the whole round (every epoch's planes and every step as
    they were before it), and the rounds end (docs/RESULTS.md, START3: world 382 at 6 mm,
    a refused step whose epoch kept its new planes)."""

    start_redeskew_test: Literal["move", "information", "significant"] = "move"
    """With ``start_redeskew: converged``, when the mean of the start's velocities counts
    as converged: ``move``, once a step moves it by less than its standard error (a coin
    toss with two steps: 2D-rig world 382 at 6 mm stopped on two steps whose lateral
    noise agreed); ``information``, that and the mean's information at least four times
    the first averaged step's in every direction (the start's deskewing error, the first
    step's velocity error over the sweep, at least halved in standard deviation)
    (:func:`planodom.odometry.start_converged.informed`); ``significant``, ``information``
    and the mean's correction of the velocity epoch 0 was deskewed with beyond the
    mean's covariance (chi-square 95 %, 2 DoF: a correction within its noise changes
    the start's planes by the new extraction more than by the deskewing; built after
    START4's decision) (docs/RESULTS.md, START4)."""

    start_redeskew_translation_guard: bool = False
    """With ``start_redeskew: converged``, a step estimated again is refused also when its
    own x, y velocity disagrees with the first estimate's beyond the sum of their
    covariances (chi-square 99 %, 2 DoF), beside the rotation guard (2D-rig world 398 at
    6 mm: a re-estimated step 2.43 m/s for a first 1.97 and a true 2.0; docs/RESULTS.md,
    START3 and START4)."""

    start_redeskew_rate: Literal["step", "kept"] = "step"
    """With ``start_redeskew: converged``, the angular rate each epoch of the start is
    deskewed with again: ``step``, its step's own; ``kept``, the one it was deskewed with
    (only the speed is the converged quantity: a step's own rate, changed, turns the
    steps estimated again beyond their covariances, refused by the guard on 2D-rig
    worlds 382, 390 and 396 at 6 mm; docs/RESULTS.md, START3)."""
