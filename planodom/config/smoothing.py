"""Configuration of factor-graph smoothing (planodom.smoothing)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from planodom.config.loop_candidates import Fraction, LoopCandidateConfig
from planodom.config.odometry import AngleDeg, Positive
from planodom.config.smoothing_scale import CovarianceScaleConfig
from planodom.errors import ConfigError


class SmoothingConfig(LoopCandidateConfig, CovarianceScaleConfig):
    """Factor-graph smoothing (planodom.smoothing).

    Noise models come from the data (odometry sigmas, plane fit covariances, confidences);
    the ``*_min_*`` fields are floors (noiseless simulations report zero covariances), the
    ``default_*`` fields stand in when an input carries no uncertainty at all. The loop
    candidates' and loop hypotheses' fields are :class:`.LoopCandidateConfig`'s.
    """

    delta_max: Annotated[int, Field(ge=1)] = 3
    """D: relative poses (and associations) between epochs k - delta and k, delta = 1..D."""
    window: Annotated[int, Field(ge=2)] = 10
    """W: epochs kept by the fixed-lag smoother (windowed mode); needs W > D."""
    windowed_backend: Literal["incremental", "batch"] = "incremental"
    """"incremental" (gtsam.IncrementalFixedLagSmoother, iSAM2) or "batch"
    (gtsam.BatchFixedLagSmoother, Levenberg-Marquardt over the window)."""
    plane_factor: Literal["auto", "global", "anchored"] = "auto"
    """"global" (gtsam.OrientedPlane3Factor, world-frame landmark), "anchored"
    (LocalOrientedPlane3Factor, landmark in an anchor frame near its observations) or "auto":
    global for landmarks first seen within ``global_plane_max_distance_m`` of the world
    origin when no robust kernel is asked for planes, anchored otherwise."""
    global_plane_max_distance_m: Positive = 30.0
    """auto: farthest first-observing position (m) for a global plane factor."""
    min_landmark_epochs: Annotated[int, Field(ge=2)] = 2
    """A tracked plane enters the graph once seen in at least this many epochs."""
    flipped_normals: Literal["flip", "reject"] = "flip"
    """A measured normal more than 90 deg from the predicted one: "flip" it or "reject" it."""
    gate_normal_deg: AngleDeg = 15.0
    """After orientation, a plane observation whose normal is farther than this from its
    landmark's prediction (at the initial estimate) is a wrong association: not added."""
    gate_offset_m: Positive = 2.0
    """Same for the offset along the normal, metres (allows odometry drift along a track)."""
    robust_kernel: Literal["none", "huber", "cauchy"] = "cauchy"
    """"none", "huber" or "cauchy", on the factors chosen by ``robust_between`` and
    ``robust_planes`` (outlier associations, wrongly extracted planes). Cauchy: its
    influence vanishes for gross outliers, while Huber's stays at threshold / sigma per
    factor, so one precise but wrong plane outweighs several less precise right ones (a
    ground plane 2.8 deg off with a 0.01 deg sigma turned a pose by 2 deg at 2 cm range
    noise, experiments/smoothing_consistency.py)."""
    robust_threshold: Positive | None = None
    """Kernel parameter in whitened units (sigmas); None: 1.345 (Huber), 2.3849 (Cauchy)."""
    robust_between: bool = True
    """Robust kernel on the 5-DoF between factors."""
    robust_planes: bool = True
    """Robust kernel on the plane factors (forces anchored plane factors in auto mode)."""
    default_rotation_sigma_rad: Positive = 0.005
    """Per-axis rotation sigma of a relative pose without sigmas, rad."""
    default_translation_sigma_m: Positive = 0.05
    """Per-axis horizontal translation sigma of a relative pose without sigmas, m."""
    min_rotation_sigma_rad: Positive = 1e-6
    """Floor of the between factors' rotation sigmas, rad (added in quadrature; the
    odometry floors its own sigmas, ``odometry.min_sigma_*``)."""
    min_translation_sigma_m: Positive = 1e-5
    """Floor of the between factors' translation sigmas, m."""
    default_plane_normal_sigma_rad: Positive = 0.01
    """Normal sigma (per tangent axis) of a plane without covariance, rad."""
    default_plane_offset_sigma_m: Positive = 0.02
    """Offset sigma of a plane without covariance, m."""
    min_plane_normal_sigma_rad: Positive = 1e-6
    """Floor added (in quadrature) to the plane factors' normal sigmas, rad: a guard for
    planes without uncertainty (synthetic data). It must stay far below the fit's
    uncertainty: added to the diagonal, it spoils the fit's strong normal-offset
    correlation, and the former 1e-4 rad and 1 mm made the plane covariances (median
    NEES 0.7 against chi2(3)'s 2.4) and the smoothed poses three times too cautious at
    6 mm range noise."""
    min_plane_offset_sigma_m: Positive = 1e-5
    """Floor added (in quadrature) to the plane factors' offset sigma, m."""
    plane_confidence_scaling: bool = False
    """Diagnostic (experiments/smoothing_consistency.py): also divide a plane's covariance
    by its CPEF confidence. Off: the TLS covariance already grows with the fit residual and
    shrinks with point count and extent, and on the simulated loop it matches the planes'
    errors (median NEES 2.3 against chi2(3)'s 2.4 at 6 mm and 2 cm), while dividing by the
    confidence (median 0.4-0.5) made it two to three times too cautious."""
    between_factors: Literal["all", "untracked", "none"] = "untracked"
    """Which resolved relative poses become 5-DoF between factors. "all": every one.
    "untracked": only those whose source planes (the odometry's winning rotation and
    translation pairs, ``RelativeMeasurement.sources``) are not plane factors of a shared
    landmark in both epochs already: a relative pose is a function of its planes, so
    adding it beside their plane factors counts the same measurements twice (up to 2 D
    times with D deltas): "all" makes the smoothed poses' NEES 10-40 % larger (e.g. 4.9
    against 3.6 on the loop, 7.1 against 5.2 in the canyon at 2 cm) at the same or a
    worse ATE (experiments/smoothing_consistency.py). Relative poses without sources
    (independent sensors) are always factors. "none": no between factors (plane factors
    only; a diagnostic of the consistency experiment), except the fallback factors."""
    deskew_noise: Literal[
        "none",
        "twist_change",
        "twist_change_net",
        "twist_change_offsets",
        "twist_change_frame",
        "twist_change_frame_net",
        "twist_change_jacobian",
        "twist_change_jacobian_net",
    ] = "none"
    """"twist_change": the plane and between factors' covariances also hold the deskewing
    error the fits' covariances miss, from the run's own changes of motion around each
    epoch (planodom.smoothing.deskew_noise; batch: the whole run's, fixed-lag: so far).
    Every mode but "none" assumes each epoch's points are spread over its time span and
    deskewed with a constant twist. Epochs taken at one instant (``RelativePose.time_spread``
    False: the scan's points share one time; every relative pose carries it, those
    estimated from planes too when their scans were known, ``smoothing.run.relative_poses``)
    get none of it; scans deskewed before planodom look spread: there it only adds caution.
    On snapshot scans (``planodom experiment smoothing --levels 0.006,0.02 --epochs 300``)
    every mode now gives what "none" gives (before the flag reached the relative poses
    from planes, "twist_change_frame_net" brought the paper loop's mean NEES5 to 0.49 and
    the canyon's fixed-lag ATE at 2 cm from 0.0098 to 0.030 m). A loop factor takes the
    error of both its epochs (:meth:`.DeskewNoise.loop_covariance`). The default stays
    "none" because on full laps of the 2D-rig worlds 0, 8, 14 (batch with loops) the ATE
    moved both ways by millimetres (world 14 at 2 cm 17.4 -> 20.1 mm, 2000 epochs of world 0
    at 6 mm 32.8 -> 34.3 mm; world 8 at 2 cm 92 -> 89 mm) while the mean NEES5 fell from
    330-3050 to 9-48. Choose "twist_change_frame_net" for scans spread in time that
    planodom deskews when the covariances matter (the figures below are for such scans);
    "twist_change_net": the same less the variance the odometry's covariances declare;
    "twist_change_offsets": the planes get its translation part only (their offsets);
    "twist_change_frame": none of it in the plane factors' covariances: each epoch has a
    deskewed frame F(k) (Pose3) tied to its pose with the epoch's deskewing covariance,
    its plane factors and the between factors joining two such epochs are on the F's
    (one error shared by the epoch's planes, as the deskewing error is; independent
    inflation of every plane down-weights good geometry and cost ATE); "..._frame_net":
    the same, less the odometry's declared variance; "none": the fits' and the
    odometry's covariances alone. With suspension sway on the procedural worlds the
    deskewing was the dominant error of the planes' normals (1 mrad against fit sigmas of
    0.03 mrad) and of the relative poses' roll (18 sigmas). Measured (batch, mean NEES5 of
    the smoothed poses / ATE; chi2(5) 95 % per run [0.83, 12.8]), none -> twist_change ->
    twist_change_frame_net: procedural worlds (200 epochs, batch+loops, xy ATE m) 0 (2D
    rig) 6 mm 518 / 0.383 -> 2.7 / 0.313 -> 1.9 / 0.377, 2 cm 147 / 0.528 -> 3.6 / 0.574 ->
    5.5 / 0.531; world 2 (2D rig) 6 mm n/a / 1.57 -> n/a / 0.86 -> n/a / 1.09, 2 cm 2148 /
    0.070 -> 9.3 / 0.290 -> 20.9 / 0.063; world 1 (lidar16, none -> frame_net) 6 mm
    4736 / 0.0070 -> 273 / 0.0070, 2 cm 1286 / 0.0087 -> 33 / 0.0087. Built-in scenes (experiment
    consistency, continuous motion, 150 epochs, ATE mm): paper loop 6 mm 40 / 2.3 -> 0.97 / 2.1 ->
    2.3 / 2.3, 2 cm 7.5 / 3.7 -> 1.8 / 13 -> 0.68 / 3.7; canyon 6 mm 15.9 / 40 -> 1.2 / 67 -> 1.2 /
    40 (2 cm: 8.2 / 199 in all); "planodom smooth" on the canyon (200 epochs) 4.0 mm in none and
    frame_net. "twist_change_offsets" left the NEES out (paper loop 37, canyon
    15) and cost ATE (paper loop 2 cm 10 mm). "twist_change_frame" (measured with the between
    factors still on the poses, with the term) erred on the cautious side (paper loop 0.61 / 0.15,
    canyon 0.28; its changes hold the odometry's noise). Earlier (an older main, independent
    inflation): lidar worlds 1 and 3 stayed far off (36-3386); "twist_change_net" lost world 2 at 2
    cm (ATE 3.5 -> 17 m).
    "twist_change_jacobian": each plane factor gets the epoch's change of motion through
    the plane's own first-order change with the deskewing twist (``Plane.deskew_jacobian``:
    when and where along the plane its points were seen, not a rigid perturbation of the
    epoch's frame), and, for a step whose z the odometry did not measure, the run's
    measured vertical motion as its vertical error; the between factors as in
    "twist_change"; "..._jacobian_net": less the odometry's declared variance. At the true
    poses of world 16 (6 mm), with exactly deskewed points the fits' covariances are
    consistent (plane NEES3 3.0) and the whole excess (315) is the deskewing; this term
    predicts it (correlation 0.93-0.998, slope 1.0-1.06) and leaves NEES3 2.0. Measured
    (300 epochs, 6 mm, plane NEES3 median / share beyond chi2(3) 99.9 %; ATE m batch /
    batch+loops; mean NEES5 batch+loops), none -> frame_net -> jacobian: world 16 107 /
    0.76, 0.662 / 0.006, 188 -> 2.7 / 0.27, 0.673 / 0.007, 3.1 -> 1.0 / 0.046, 0.373 /
    0.005, 4.2 (odometry 0.067); world 2 552 / 0.91, 1.145 / 0.128, 4261 -> 2.5 / 0.24,
    1.159 / 0.222, 5.9 -> 0.96 / 0.041, 1.504 / 0.125, 1.6 (odometry 0.817); world 0 58 /
    0.77, 0.240, 465 -> 2.1 / 0.12, 0.234, 7.0 -> 0.79 / 0.010, 0.121, 4.1 (odometry 0.249).
    Built-in canyon (experiment consistency inputs, continuous, 200 epochs, batch+loops ATE
    m / NEES5): 6 mm 0.035 / 17 -> 0.035 / 1.4 -> 0.041 / 4.6, 2 cm 0.201 / 8.0 -> 0.201 /
    3.7 -> 0.161 / 3.8; "planodom smooth" canyon 200 epochs ATE 3 -> 3 -> 5 mm. Not the
    default: it costs millimetres on the canyon at 6 mm, and the batch without loops stays
    worse than the odometry on world 16 and 2, where degenerate and unresolved stretches
    (along-track unobserved, a weak constant-velocity fallback) carry the error. On full
    laps of the ten 2D-rig worlds (batch with loops, none -> jacobian): mean NEES5 inside
    the 95 % interval on 11 of 20 runs (none: 0), median ATE 0.053 -> 0.033 m (6 mm) and
    0.085 -> 0.085 m (2 cm), but worse on 8 of the 20 runs, and the fixed-lag smoother
    without loops at 2 cm 0.65 -> 1.75 m (median)."""
    fallback_start: Literal["first_step", "identity"] = "first_step"
    """Batch: the fallback factor's mean into an epoch before the odometry's first
    measured translation (rotation-only or unresolved with no velocity known yet):
    "first_step": the first measured delta = 1 step (the whole run is known: constant
    velocity backwards in time); "identity": no motion (what an online smoother can
    say; the fixed-lag smoother always does). A run that starts at speed makes identity
    a wrong prediction that the fallback's sigma does not cover: on the 2D-rig procedural
    world 18 (full lap, batch with loop closure) epochs 1-2 are rotation-only, identity
    was 0.75 m off per epoch and the whole lap kept that offset (the loop's correction
    shared between them and the rotation-only epochs before the lap's end). ATE m,
    identity -> first_step: world 18 6 mm 0.660 -> 0.196, 2 cm 0.852 -> 0.377; world 6 2 cm
    1.53 -> 1.69 (174 of its 204 epochs bridged); 0, 2, 4, 8, 10, 16 within 1 mm."""
    fallback_step: Literal["last", "medoid"] = "medoid"
    """The fallback factor's mean into an epoch whose translation nothing measured, when the
    odometry gave no unresolved prediction for it (rotation-only epochs): "last": the last
    measured delta = 1 step repeated; "medoid": the medoid of the last five measured steps
    (:func:`planodom.smoothing.motion.medoid_transform`), so that one wrong step is not repeated.
    On 2D-rig world 4 at 2 cm (batch with loops, coplanar deskewing) one measured step 22 cm
    off before 14 rotation-only epochs was repeated by every fallback: "medoid" 0.67 ->
    0.069 m ATE (world 16 at 6 mm 0.019 -> 0.025 m; figures at ``odometry_deskew_twist``)."""
    relative_prior: Literal["odometry", "measured_steps"] = "odometry"
    """Prior of the relative poses delta = 2..D (``smoothing.run.smoothing_relatives``): the
    odometry's chain, or with "measured_steps" each step it did not measure the translation
    of given the medoid translation of the last measured steps (``motion.measured_step_prior``;
    a rotation-only result's translation is no measurement; figures in docs/RESULTS.md).
    Measured again on one lap of the 2D-rig worlds 0, 2, .., 18 (batch with loops, this
    default otherwise): median ATE 0.0133 -> 0.0134 m at 6 mm, 0.0506 -> 0.0313 m at 2 cm
    (world 4 0.069 -> 0.027), but world 2 at 6 mm 0.035 -> 3.64 m (a map match 2.3 m off
    along a corridor passed the chained drift, the tracked correction walked 5 m: 89 wrong
    ties kept), world 6 0.078 -> 0.099 (6 mm) and 0.253 -> 0.327 m (2 cm). With
    ``loop_verify_drift`` and ``loop_drift_yaw`` "run": world 2 at 6 mm 0.035 m, medians
    0.0134 and 0.0315 m, better on 4 runs of 20, worse on world 6 at 6 mm (0.078 -> 0.129 m;
    chaotic there: 0.05-0.14 m across these switches): off."""
    vertical_sigma_m: Positive = 0.05
    """Weak prior on the change of height between consecutive epochs, m (z is unobserved
    by the 5-DoF factors; see planodom.smoothing.graph)."""
    fallback_rotation_sigma_rad: Positive = 0.05
    """Constant-velocity between factor for an epoch whose horizontal translation no
    relative pose measured (unresolved or rotation-only), rad."""
    fallback_translation_sigma_m: Positive = 0.5
    """Translation sigma of that fallback factor, m."""
    prior_sigma: Positive = 1e-4
    """Sigma of the prior fixing the first pose (gauge), rad and m."""
    max_iterations: Annotated[int, Field(ge=1)] = 100
    """Levenberg-Marquardt iterations (batch)."""
    relative_error_tol: Annotated[float, Field(gt=0, lt=1)] = 1e-4
    """Levenberg-Marquardt stops when the error decreases by less than this fraction (with
    robust kernels the last iterations creep: 1e-6 triples the time for < 0.1 % of ATE)."""
    relinearize_threshold: Positive = 0.01
    """iSAM2 relinearisation threshold (incremental windowed backend)."""
    relinearize_threshold_planes: Positive | None = None
    """Its landmarks' own (None: the same), for those no marginal holds; 1e-5 mixed (RESULTS)."""
    windowed_factorization: Literal["auto", "QR"] = "auto"
    """iSAM2's factorisation: "auto" Cholesky, QR from the first update Cholesky finds
    indeterminant on (rebuilt from its state); "QR" throughout (planodom.smoothing.windowed)."""
    compute_covariances: bool = True
    """Batch: marginal covariances of the poses (gtsam.Marginals)."""
    covariance_inlier_quantile: Fraction | None = 0.99
    """Batch covariances: a robust factor whose squared whitened error at the estimate is
    within this quantile of chi2(its dimension) counts with full (Gaussian) weight, others
    with the robust kernel's weight (planodom.smoothing.batch_covariances.covariance_graph); the
    kernel's down-weighting of inliers would otherwise inflate the covariances by about
    1.5 (Cauchy). None: the robust weights throughout."""
    covariances_relative_to_first: bool = True
    """Batch: the poses' covariances are relative to the first pose (conditioned on it),
    as the poses are: the first pose's prior (``prior_sigma``) only fixes the gauge, and
    its uncertainty would otherwise be added to every pose's (``prior_sigma`` times the
    distance in translation). False: gtsam's marginals with that prior."""

    batch_initial: Literal["odometry", "windowed", "checked"] = "windowed"
    """Batch: initial guess (and loop closure's predictions) from the chained odometry, or the
    fixed-lag smoother run first (it follows the planes through odometry failures), or
    "checked": that one unless its motion contradicts the odometry's beyond the run's drift
    (then the chained; planodom.smoothing.initial_check; docs/RESULTS.md, LAP362)."""
    loop_closure: bool = True
    """Batch: re-identify planes of a global map near the predicted pose and tie revisited
    landmarks (planodom.smoothing.loops); off: landmarks only from the tracks (delta <= D)."""
    windowed_loop_closure: bool = False
    """Fixed-lag smoothing: the same global map and matching at every
    ``windowed_loop_every_epochs``-th epoch (the keyframes); a landmark that has left the
    window re-enters it with its marginal as prior (planodom.smoothing.windowed_loops).
    Also used by batch smoothing's windowed initial guess (``batch_initial``).
    Off by default: it pays on a 2D rig and not on lidar, and this switch is not per rig.
    Measured (``planodom experiment loops``, one lap of procedural worlds 0, 2, .., 10,
    2D rigs): median ATE 0.38 -> 0.23 m at 6 mm, 1.47 -> 1.21 m at 2 cm, loop-end error
    0.77 -> 0.02 m and 1.40 -> 0.24 m, never worse on a run, at about 250 instead of
    550 epochs/s (15 wrong ties kept on one world, whose ATE still fell). On lidar (worlds
    1 and 3, 6 mm) the ATE moved by 3 mm and 1 mm while the time rose 2.3-fold (lidar32:
    27 -> 12 epochs/s). As batch's initial guess (same worlds) it changed the batch with
    loop closure on world 2 only, both ways: 8.3 -> 0.65 m at 2 cm, 2.8 -> 54 m at 6 mm.
    Turn it on for a 2D rig's fixed-lag (online) output."""
    windowed_loop_every_epochs: Annotated[int, Field(ge=1)] = 1
    """Keyframes of fixed-lag loop closure: match against the map every N-th epoch."""
    loop_every_epochs: Annotated[int, Field(ge=1)] = 1
    """Match against the map at every N-th epoch only (keyframes: fewer ties on dense lidar
    data). Default 1: on a 32-beam lidar lap (procedural world 3, 6 mm, 632 epochs, 50
    planes an epoch) every 5th epoch tied 893 instead of 4 808 observations but saved no
    time (matching is a tenth of it: the windowed initial guess and the pose covariances
    dominate) and raised the ATE from 0.154 to 0.169 m."""
    loop_min_gap_epochs: Annotated[int, Field(ge=1)] = 50
    """A map landmark is a re-identification candidate once unseen for this many epochs."""
    loop_radius_m: Positive = 20.0
    """Map landmarks whose support comes within this of the predicted position are
    candidates, m."""
    loop_max_candidates: Annotated[int, Field(ge=2)] = 24
    """At most this many candidates (the nearest) per epoch: LDA's cost grows with the
    square of the plane pairs."""
    loop_drift_fraction: Positive = 0.05
    """Largest translation bound of a re-identification: this fraction of the distance
    driven since the candidates were last seen (plus ``loop_min_translation_m``)."""
    loop_sigmas: Positive = 3.0
    """Bounds of a re-identification: this many standard deviations of the odometry chained
    since the candidates were last seen (its covariances; the fallback sigmas for an
    epoch it did not measure), capped by the drift fraction / rotation per metre."""
    loop_min_translation_m: Positive = 0.5
    """Smallest translation bound of a re-identification, m."""
    loop_rotation_deg_per_m: Positive = 0.1
    """Largest rotation bound of a re-identification per metre driven since last seen (plus
    the association's ``prior_rotation_deg``), degrees; at most 45."""
    loop_min_matches: Annotated[int, Field(ge=2)] = 3  # strict associations of a re-identification
    loop_accept_degenerate: bool = True
    """Also accept a match of rotation only (one old wall and the ground; gated after)."""
    loop_verify: Literal["off", "consistency", "tracked"] = "tracked"
    """Verification of every match against the map before tying (planodom.smoothing.loops):
    "consistency": the correction of the chained guess it implies must agree, within the
    chained odometry's covariance since then (chi2 at ``loop_gate_quantile``), with the
    last accepted one; a new correction is taken only once ``loop_confirmations`` matches
    agree on it. "tracked": the same, and once a correction is accepted the map is matched
    around the corrected prediction with bounds grown from its epoch (not from the
    candidates' last sighting). "off": every match of full rank ties."""
    loop_refuse_misfit: bool = True
    """Refuse a rotation-only re-identification (its translation unverified) when a tied
    wall's offset residual at the match's own pose exceeds chi2(1) at
    ``loop_gate_quantile`` under the drift since the accepted correction along the wall's
    normal plus both planes' offset variances, or when two ties of parallel walls
    disagree on the pose along their normal (chi2(1) under the planes' variances alone:
    the drift cancels) (planodom.smoothing.match_fit). A fixed 0.35 m bound refused 221
    right matches on world 4 at 2 cm (ATE 0.025 -> 0.126 m); the drift-scaled one none.
    Measured (batch, loop closure, worlds 0, 2, 4 at 6 mm and 2 cm, one lap): world 2 at
    6 mm keeps 4 instead of 20 wrong ties (ATE 2.77 -> 2.68 m), the others unchanged."""
    loop_refuse_ambiguous: Literal["off", "drift", "stated", "parts", "run"] = "off"
    """Test each re-identification against its competing hypotheses: one tie swapped for
    another old wall parallel to it (same orientation), the pose shifted to fit, under the
    prediction's uncertainty; a tie whose competitor costs at most chi2(1) at
    ``loop_gate_quantile`` more (a likelihood ratio, planodom.smoothing.match_fit) is not
    made, and its match is verified as a rotation-only one on its other ties (refused
    without any). A competitor the map's own drift between the two walls' sightings
    explains is the same wall seen twice, no competitor. Loop candidates refuse an
    old-epoch match with such a competitor among the old epoch's planes. The prediction's
    uncertainty: "drift" the verification's (the fallback's yaw variance for rotation-only
    epochs), "stated" as the odometry states it (their measured yaw); "off": no test.
    Measured (batch, one lap, ATE m off -> drift, wrong ties kept): 2D-rig world 2 at 6 mm
    2.99 -> 0.089 (46 -> 0), world 16 at 6 mm 0.107 -> 0.209 (0 -> 0), world 16 at 2 cm
    3.52 -> 3.43 (143 -> 143), worlds 0, 6 and world 2 at 2 cm within 5 mm. Off by
    default: it makes world 16 at 6 mm worse. On world 16 a wrong tie passes every check
    because the chained guess through rotation-only epochs is metres off (their relative
    poses' translation, not the constant velocity), not because two walls compete.
    "parts": as "drift", and each tie's offset variance also holds the map's drift
    between its wall's sighting and the nearest other tied wall's (a wall of another
    map part shares no frame with the other ties, so they cannot confirm an alias of
    it). Why: on held-out world 32 (indoor, 3.17 m between parallel walls) 43 epochs
    with the translation unobserved shifted the map's early part 3.2-3.8 m along a
    corridor, one wall spacing; a wall of that part tied one spacing off then fits the
    ties to the later parts exactly (competitor's chi2 4478), and the map took it.
    Measured (one lap, batch+loops ATE m, off -> parts, wrong ties kept): world 32 at
    6 mm 3.61 -> 3.05 (29 -> 17), at 2 cm 3.28 -> 2.82 (118 -> 23, loop end 3.46 -> 0.16
    m); world 26 identical; world 0 at 2 cm 0.148 -> 0.130; worse: world 16 at 6 mm
    0.025 -> 0.042, at 2 cm 0.021 -> 0.071 (its 9 right loop factors refused), world 4
    at 2 cm 0.069 -> 0.128 (world 0 and 4 at 6 mm within 0.3 mm). "drift" alone: world
    32 at 6 mm 3.61, world 16 0.034 and 0.021, world 4 at 2 cm 0.128 (the test's, not the
    parts'). "run" (needs ``loop_candidate_drift`` "run"; loop candidates unchanged): the
    prior and map drift the run's (:func:`.loop_drift.run_drift`), "parts", and no "same
    wall" exclusion. Why: world 32 at 2 cm, its first wrong ties' true wall 2.6-3.8 m off,
    chained sigma 3.7-10.6 m (a spacing apart passes as one wall), the run's 2.2-3.7 m.
    Measured (docs/RESULTS.md "An honest alias test"; ATE m, off -> run): world 32 at 2 cm
    wrong ties kept 17 -> 8, loop end 3.71 -> 0.04 m, but 2.80 -> 3.85 (the odometry's
    3.8 m loss exceeds a wall spacing: every tie undoing it is ambiguous); 6 mm 0.142 ->
    0.128; world 4 at 2 cm 0.017 -> 0.065 (one wall mapped twice 0.3 m apart competes with
    itself), world 16 0.023 -> 0.035. Off by default."""
    loop_confirmations: Annotated[int, Field(ge=1)] = 2
    """Matches that must agree before a new (or the first) correction is accepted."""
    odometry_deskew_twist: Literal["coplanar", "odometry"] = "coplanar"
    """Batch (offline, ``planodom smooth``): the twist the odometry it runs deskews each
    epoch with. "coplanar": ``odometry.deskew_twist: coplanar`` (the twist fit to the
    epoch's own planes, slower); "odometry": as ``odometry.deskew_twist`` says (the
    streaming default). The fixed-lag smoother (online) always keeps the odometry's.
    Measured on one lap of the 2D-rig procedural worlds 0, 2, .., 18 (batch with loops,
    odometry -> coplanar): median ATE 0.053 -> 0.013 m at 6 mm and 0.085 -> 0.058 m at
    2 cm, worst 0.20 -> 3.06 m and 1.69 -> 0.67 m, below the oracle's odometry on 4 and
    5 runs of 10 either way; better on 17 of the 20 runs (world 8 at 6 mm 0.077 -> 0.011,
    world 18 0.196 -> 0.051, world 6 at 2 cm 1.69 -> 0.24), but world 16 at 6 mm 0.107 ->
    3.06 m (21 of its 28 loop-candidate factors wrong, up to 4.6 m, kept: aliased along
    its corridor) and world 4 at 2 cm 0.013 -> 0.67 m (loop end 0.84 m). Both failures
    were the loop closure's and the graph's (``loop_candidate_drift`` "run",
    ``fallback_step`` "medoid"); with them, the default (the same lap, old default -> now):
    median ATE 0.053 -> 0.013 m at 6 mm and 0.085 -> 0.051 m at 2 cm, worst 0.20 -> 0.078 m
    and 1.69 -> 0.25 m, below the oracle's odometry on 5 and 5 runs of 10, better on 18 of
    the 20 runs, no wrong plane tie kept; worse on world 4 at 2 cm (0.013 -> 0.069 m, see
    ``relative_prior``) and world 0 at 2 cm (0.138 -> 0.148 m); loop end median 1.1 -> 0.6
    and 1.7 -> 1.0 cm, world 18's 10.5 and 11.5 cm (see ``loop_candidate_old``). The
    odometry takes 1.2-2.5 times as long."""
    redeskew_passes: Annotated[int, Field(ge=0, le=3)] = 0
    """Batch, on scans with point times: after smoothing, deskew every scan again along a
    curve through the smoothed poses (:func:`planodom.odometry.run.redeskewed_run`), run
    the odometry and the relative poses again on them and smooth again; this many times
    (0: the streaming deskewing only). Off by default: deskewing needs the motion within
    an epoch and its neighbours, which loop closure does not improve (it removes drift).
    Measured on one lap of the 2D-rig procedural worlds 0, 2, .., 18 at 6 mm and 2 cm
    (batch with loops, one pass): median ATE 0.053 -> 0.047 m at 6 mm, 0.085 -> 0.111 m
    at 2 cm, below the oracle's odometry on 7 runs of 20 instead of 9, worst 2.4 m
    (world 16 at 2 cm, from 0.045 m), about 2.7 times the time; two passes kept 148 wrong
    ties. Again on the coplanar default (worlds 0, 2, 4 only, one pass): world 2 at 6 mm
    0.035 -> 2.99 m (42 wrong ties), at 2 cm 0.068 -> 2.83 m, world 4 at 6 mm 0.007 ->
    0.138 m, world 0 at 2 cm 0.148 -> 0.130 m. On worlds 8 and 18 at 6 mm the smoothed poses'
    step errors were no smaller than the odometry's (0.073 against 0.067 deg rms, 0.38
    against 0.25), where deskewing along the true poses gives 0.0015 and 0.011 m (today
    0.077 and 0.196 m), and along the true poses with independent errors of 0.02 deg and
    5 mm still 0.008 and 0.015 m.
    On the simulated urban canyon (200 epochs) one pass takes the batch's rotation RPE
    from 0.016 to 0.0067 deg (ATE 4.0 -> 3.5 mm)."""
    first_epoch_refresh: Annotated[int, Field(ge=0, le=5)] = 0
    """Batch, on scans with point times: after smoothing (and ``redeskew_passes``),
    extract the first epoch again with the constant twist of its smoothed step to the
    second, this many times (each with the step estimated on the planes before), estimate
    the relative poses from it again and smooth again (0: off;
    :func:`planodom.smoothing.redeskew.refresh_first_epoch`). Off by default: measured on
    one lap of the 2D-rig procedural worlds 0, 2, .., 18 (batch with loops), 1 time:
    median ATE 0.053 -> 0.038 m at 6 mm and 0.085 -> 0.068 m at 2 cm (world 0 at 6 mm
    0.029 -> 0.011, world 8 0.077 -> 0.064, 3 times 0.050; world 18's loop end 0.106 ->
    0.012 m), but world 16 at 6 mm 0.107 -> 2.2 m (103 wrong ties kept) and world 2 at
    2 cm 0.34 -> 0.71 m; below the oracle's odometry on 8 runs of 20 instead of 9; about
    2.5 times the time (a second solve with loops). On the simulated paper loop at
    sigma = 0 it changes nothing (the first epoch already has its planes). Measured again
    on the coplanar default with the loop hypotheses' clique (same laps): 6 mm median ATE
    0.0133 -> 0.0104 m, loop end below 10 cm on every world (world 18 0.0496 -> 0.0164 m,
    loop end 10.5 -> 0.7 cm; world 6 0.078 -> 0.051), below the oracle on 6 of 10; 2 cm
    median 0.0506 -> 0.0522 m (world 18 0.065 -> 0.024, loop end 11.5 -> 2.0 cm), but world
    16 at 2 cm 0.021 -> 4.62 m: two loop hypotheses aliased 4.6 m along its corridor (23
    factors) outnumber the right one (4) in the clique, and the map's accepted correction
    (0.76 m off in truth) does not refuse them (their drift spans the whole lap); world 2
    0.035 -> 0.049 (6 mm), 0.068 -> 0.098 m (2 cm). With ``loop_consistency:
    hypotheses_and_map`` (the clique weighs the map's ties) world 16 at 2 cm is 0.034 m and
    the 2 cm median 0.0347 m, the rest as above (see that field)."""
    redeskew_trust: Literal["smoothed", "odometry"] = "smoothed"
    """``redeskew_passes``: the smoothed poses a scan is deskewed along ("measured" in
    :func:`~planodom.odometry.run.redeskewed_run`; an epoch within ``odometry.deskew_order``
    of an untrusted one keeps the streaming deskewing): "smoothed" all but the first
    epoch's, "odometry" also not those of epochs the odometry left unresolved (bridged by
    constant velocity). The first epoch's never: its pose is the least supported of the
    smoothed ones (few planes, extracted before any twist was known); trusted, it deskewed
    world 8 at 6 mm into no plane and left the next epoch unresolved (ATE 1.9 m)."""

    def model_post_init(self, context: object, /) -> None:
        """Cross-field checks (one-line :class:`ConfigError` naming the field)."""
        self.check_loop_drift()
        if self.window <= self.delta_max:
            raise ConfigError(
                f"smoothing.window: must exceed delta_max ({self.delta_max}), got {self.window}"
            )
        if self.covariance_model == "sandwich" and (
            self.deskew_noise != "none" or self.covariance_scale != "none"
        ):
            raise ConfigError(
                "smoothing.covariance_model: 'sandwich' models the deskewing error the noise "
                "models leave out: needs deskew_noise and covariance_scale 'none'"
            )
        robust_planes = self.robust_planes and self.robust_kernel != "none"
        if self.plane_factor == "global" and robust_planes:
            raise ConfigError(
                "smoothing.plane_factor: 'global' takes no robust kernel "
                "(gtsam.OrientedPlane3Factor accepts only Gaussian noise): "
                "set robust_planes to false or plane_factor to 'anchored' or 'auto'"
            )
