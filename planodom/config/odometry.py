"""Configuration of consensus and the streaming odometry (association: :mod:`.association`)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from planodom.config.association import AcuteDeg, AngleDeg, AssociationConfig, Positive
from planodom.config.odometry_guards import DeskewGuards

__all__ = ["AcuteDeg", "AngleDeg", "AssociationConfig", "OdometryConfig", "Positive"]


class OdometryConfig(DeskewGuards):
    """Rotation / translation consensus and the divide-and-conquer pipeline.

    Pipelines (paper Fig. 3): ``"wocsc"`` = (LDA, WOCSC rotation, WOCSC translation);
    ``"sda-mean"`` = (LDA, WOCSC rotation, SDA, mean translation "cog"); ablations
    ``"ocsc"`` = unweighted consensus for both, ``"mean"`` = chordal mean rotation of all
    LDA candidates, SDA and mean translation. Beyond the paper: ``"map"`` = plane-landmark
    odometry against a local plane map with point-to-plane costs from plane moments
    (:mod:`planodom.odometry.planemap`, section ``planemap``); ``"auto"`` = "map" for
    scans on the lidar extraction path, "wocsc" for the 2D rig (and for plane lists
    without scans, and for ``delta`` > 1).
    """

    pipeline: Literal["auto", "map", "wocsc", "sda-mean", "ocsc", "mean"] = "auto"
    """The pipeline (see the class docstring). Default auto: measured, the map pipeline
    is far better on recorded and simulated lidar, the paper's wocsc on the 2D rig (see
    docs/ARCHITECTURE.md)."""
    delta: Annotated[int, Field(ge=1)] = 1
    """Associate epoch k with epoch k - delta (paper's future work: delta > 1)."""
    rotation_inlier_deg: AngleDeg = 3.0
    """A plane association agrees with a rotation when the normals match within this."""
    translation_inlier_m: Positive = 0.1
    """A pair agrees with a translation when its reference points match within this, m."""
    translation_min_angle_deg: AcuteDeg = 20.0
    """Pairs closer than this to parallel give no reference point (its error grows as
    1 / sin(angle)); rotation uses every non-parallel pair."""
    refinement: Literal["none", "translation", "pose", "moments"] = "translation"
    """After the consensus: ``"translation"`` re-associates (SDA) and solves the translation
    by weighted least squares over all associated planes (:mod:`planodom.odometry.refine`),
    walls a few degrees apart in yaw measuring it together; ``"pose"`` the rotation too
    (Procrustes); ``"moments"`` "translation", then the pairwise odometry's 6-DoF pose over
    the planes' inlier points (:mod:`.moment_refine`); ``"none"``: the paper's consensus."""
    refine_offset_floor_m: Positive = 0.003
    """Refinement: added (squared) to every plane association's offset sigma, m (what a
    fit's covariance misses: deskewing, bend)."""
    refine_normal_floor_deg: Positive = 0.05
    """Refinement: added (squared) to every plane association's normal sigma, degrees."""
    refine_max_sigma_m: Positive = 0.03
    """Refinement: a horizontal direction of the translation is measured when its sigma
    is at most this, m (else it keeps the consensus or prior value and the epoch is
    degenerate); a few centimetres: what the constant-velocity prediction of a car
    misses in one epoch."""
    refine_unmeasured: Literal["prior", "kept", "walls", "prediction"] = "prediction"
    """Refinement of a degenerate epoch (a horizontal direction's sigma above
    ``refine_max_sigma_m``, :func:`planodom.odometry.refine.plane_translation`): ``"prior"``:
    the unmeasured direction is solved with the initial value (consensus's or prediction's) as
    a prior of sigma ``prior_translation_m``, the planes' weak information (a tilted ceiling,
    walls a few degrees off a corridor's axis) pulling it; ``"kept"``: it keeps the initial
    value exactly, the others (and z) solved with it held; ``"walls"``: x, y from the planes
    that are not level and the prior, then z (a level plane measures x, y through its tilt
    only, ~1 / sin(tilt) times its offset's error). ``"prediction"`` (default; streaming
    pairwise odometry): a direction the planes measure less well than the prediction (the
    predicted velocity sigma of :mod:`planodom.odometry.twist_sigma` times dt, at most
    ``prior_translation_m``) keeps the prediction exactly with that sigma, also in the retry
    without the prior's bounds, the others solved as "kept"; without a prediction's sigma as
    "prior". (World 52, 6 mm: with "prior" a far wall's weak pull set one step 0.19 m off along
    the only wall; the prediction carried it 20 epochs.) 2D-rig worlds 0-58 even, 150 epochs,
    prior -> prediction: ATE median 6 mm 0.070 -> 0.069 m, 2 cm 0.307 -> 0.296 (geometric mean
    of the ratios 0.84 / 0.85; 10 / 16 worlds better, 9 / 5 worse), xy per epoch median 0.95 ->
    0.89 / 3.50 -> 2.57 cm; world 52 3.83 -> 0.063 m, 6 0.75 -> 0.46 / 1.53 -> 1.01, 26 (2 cm)
    4.57 -> 2.29. Worse: 6 mm world 26 8.68 -> 9.90, 48 0.074 -> 0.131, 28 0.065 -> 0.082; 2 cm
    world 20 0.166 -> 0.337, 2 1.19 -> 1.27; rotation median at 2 cm 0.141 -> 0.147 deg (world
    6 0.42 -> 0.74). "kept": 2 cm world 0 0.79 -> 20.8 m."""
    estimate_z: bool = True
    """Estimate the vertical translation from associated ground-like planes."""
    z_plane_max_tilt_deg: AcuteDeg = 30.0
    """Up-facing planes tilted less than this from horizontal give the vertical translation."""
    use_motion_prior: bool = True
    """Streaming: use the constant-velocity prediction as prior for association."""
    retry_without_prior: bool = True
    """Solve again with the prior-free bounds when the solve under the prior is unresolved or
    degenerate (a wrong prior must not lock the odometry out); kept if OK (``retry_accepts``)."""
    deskew: bool = True
    """Streaming: deskew each epoch with the constant-velocity twist of the last estimate."""
    deskew_iterations: Annotated[int, Field(ge=0)] = 2
    """Streaming: extract a time-spread epoch again with its own estimate's twist, at most
    this many times (see the two tolerances below); 0: the prediction only."""
    deskew_twist: Literal["predicted", "coplanar"] = "predicted"
    """Streaming: the twist an epoch is deskewed with. "predicted": the one given (constant
    velocity, or refined from the epoch's step, see ``deskew_iterations``); "coplanar": that
    one as the prior of the twist that makes each extracted plane's inliers coplanar
    (:func:`planodom.extraction.twist_fit.fit_twist`, the epoch's own points,
    :mod:`planodom.odometry.coplanar`), and the epoch extracted again with it (default
    extractor only). Measured on the 2D-rig worlds 0-18 even, 150 epochs (medians over the
    worlds, in brackets median / worst ratio to the oracle), with ``coplanar_passes`` 2: at
    6 mm rotation 0.112 deg (60 / 310) -> 0.040 (22 / 204), xy 2.17 cm (15 / 85) -> 1.10
    (7.4 / 55), ATE 0.149 m (30 / 164) -> 0.075 (13 / 332), unresolved 12 -> 7; at 2 cm
    0.146 deg (24 / 69) -> 0.117 (20 / 51), 6.07 cm (11 / 82) -> 4.91 (7.0 / 46), 0.43 m (35
    / 550) -> 0.237 (14 / 490), unresolved 33 -> 18; at sigma = 0, 60 epochs, worlds 0 / 4 /
    8: 0.078 / 0.0093 / 0.076 deg -> 0.014 / 0.0023 / 0.011 (the twist constant over the
    epoch is the limit: deskewed with the best constant fit to the true motion, world 0
    gives 0.013 deg). Off by default: it is slower (epochs/s 3.6x fewer, median, 1.3-20x;
    0.97 -> 0.21 times KISS-ICP's), and some worlds get worse: world 12's rotation 0.039 ->
    0.055 deg at 6 mm and 0.115 -> 0.184 at 2 cm, world 4's 0.016 -> 0.023 at 6 mm (on both,
    deskewed with the true motion's best constant twist is no better: 0.022 and 0.055 deg;
    the predicted twist's errors, alike in successive epochs, cancel in their step), world
    2's (indoor) ATE 0.25 -> 0.58 m at 6 mm, world 6's 1.5 -> 2.0 m at 2 cm. With
    ``coplanar_reextract: moved`` the same figures at 0.43 (6 mm) and 0.37 (2 cm) times
    KISS-ICP's epochs/s against the default's 0.99 and 0.74 in the same runs. Neither the
    prior's weight (``coplanar_prior_scale`` 0.5 or 2: world 12's rotation 0.054 deg with
    either) nor keeping the prediction's extraction when the fit differs from it beyond
    their joint sigma (chi-square 99.9 %: world 2's ATE at 6 mm 0.58 -> 0.44 m, at 2 cm
    0.90 -> 4.2 m) removes these regressions."""
    coplanar_iterations: Annotated[int, Field(ge=1, le=20)] = 3
    """``deskew_twist: coplanar``: Gauss-Newton steps of each twist fit."""
    coplanar_passes: Annotated[int, Field(ge=1, le=5)] = 2
    """``deskew_twist: coplanar``: extract, fit the twist, and extract again this many
    times (measured, see ``deskew_twist``: 2 better than 1 at every median, 1: at 6 mm
    rotation 0.046 deg, ATE 0.074 m; at 2 cm 0.116 deg, ATE 0.39 m, worst 2228 x
    the oracle's)."""
    coplanar_planes: Literal["extract", "refit"] = "extract"
    """``deskew_twist: coplanar``: the planes with the fitted twist. "extract": the epoch
    extracted again; "refit": the planes found with the twist given fit again to their
    inliers deskewed with it (:func:`planodom.extraction.pipeline.refit`). Measured
    (``coplanar_passes`` 1, as ``deskew_twist``): refit is no faster (0.35 against 0.39
    times KISS-ICP at 6 mm) and worse, rotation 0.052 against 0.046 deg at 6 mm, ATE
    0.49 against 0.39 m at 2 cm (walls a wrong twist lost are not found again)."""
    coplanar_reextract: Literal["always", "moved"] = "always"
    """``deskew_twist: coplanar``: when a pass extracts the epoch again. "always": after
    every fit; "moved": when the fitted twist moves the planes' inliers beyond their noise
    from the twist they were extracted with (:mod:`planodom.odometry.coplanar`; warm-started
    fits that stop at a step under a tenth of a sigma). Measured, always -> moved: 2D-rig
    worlds 0-18 even, 150 epochs, odometry within 1 % (6 mm rotation 0.0402 -> 0.0401 deg,
    ATE 0.0748 -> 0.0743 m; 2 cm 0.116 deg, 0.237 -> 0.236 m), epochs/s 0.21 -> 0.43 times
    KISS-ICP's at 6 mm, 0.19 -> 0.37 at 2 cm; lidar worlds 1 / 3 / 5 / 7 unchanged. But
    ``planodom smooth``'s batch with loops (``smoothing.odometry_deskew_twist``, the
    default user of this twist; one lap of the same worlds) turned the small differences
    into large ones: world 16 at 2 cm 0.021 -> 3.02 m (19 of 46 loop factors wrong), world 6
    at 6 mm 0.078 -> 0.108 m (loop end 3.7 -> 25 cm), world 6 and 2 at 2 cm better (0.253
    -> 0.165, 0.068 -> 0.047 m), medians 0.0133 -> 0.0132 m and 0.0505 -> 0.0561 m. Hence
    "always", for the offline batch; "moved" is the faster choice when streaming."""
    coplanar_reuse: bool = False
    """``coplanar_reextract: moved``: an epoch extracted again by the deskewing policy
    starts from its last extraction (its planes and twist), not from an extraction with
    the refined twist: the fit on them with the refined twist as the prior says whether
    an extraction is needed. Measured as ``coplanar_reextract``: epochs/s 0.43 -> 0.53
    times KISS-ICP's at 6 mm, 0.37 -> 0.50 at 2 cm; 6 mm rotation 0.0401 -> 0.0444 deg
    (22 / 204 -> 22 / 205 x the oracle), xy worst 55 -> 76 x (world 8's rotation 0.028 ->
    0.040 deg), ATE 0.0743 -> 0.0746 m, worst 332 -> 183 x (world 2 0.58 -> 0.32 m); 2 cm
    rotation 0.116 deg either way, ATE 0.236 -> 0.234 m. Off: faster, not better."""
    coplanar_prior_scale: Annotated[float, Field(ge=0.1, le=100.0)] = 1.0
    """``deskew_twist: coplanar``: the prior's sigmas (:mod:`planodom.odometry.twist_sigma`)
    times this. On the lidar worlds the constant-velocity prediction lags an angular
    acceleration by several epochs, and its yaw-rate error is 2-3x the sigma the model
    gives it (world 1, 20 Hz indoor: 10-14 deg/s off in the first pass against a sigma of
    ~5; world 5: ~1 deg/s against 0.3), so the fit keeps much of it. Measured on the lidar
    worlds 1 / 3 / 5 / 7 at sigma = 0, 60 epochs (``coplanar_iterations`` 1): rotation rms
    0.023 / 0.0043 / 0.0092 / 0.0042 deg with 1, 0.0058 / 0.0041 / 0.0113 / 0.0028 with 3
    (default pipeline: 0.020 / 0.030 / 0.0075 / 0.0031); world 3's ATE 2.9 -> 7.7 mm.
    At 6 mm 3 is far worse: 0.161 / 0.054 / 0.100 / 0.166 deg against 0.058 / 0.028 /
    0.023 / 0.018 with 1 (world 3's ATE 0.28 m): with noise the yaw rate and horizontal
    velocity the planes give are off (``coplanar_axes``), so 1 stays."""
    coplanar_axes: Literal["all", "tilt"] = "all"
    """``deskew_twist: coplanar``: the twist components the fit moves. "all": the six;
    "tilt": the roll and pitch rates and the vertical velocity (what the ground, seen all
    around a spinning lidar, observes), the yaw rate and horizontal velocity kept at the
    prior (base frame z up): a wall swept across azimuth is sheared by them but stays
    nearly planar, and with noise their fit is off (lidar world 3, 6 mm: yaw-rate error
    0.15 deg/s predicted -> 0.48 fitted, forward speed 0.08 -> 0.30 m/s; roll rate 2.4 ->
    0.03 deg/s). Measured on the lidar worlds 1 / 3 / 5 / 7, 60 epochs, ``coplanar_iterations``
    1, rotation rms deg: at 6 mm predicted 0.020 / 0.031 / 0.0083 / 0.0038, coplanar all
    0.058 / 0.028 / 0.023 / 0.018, tilt 0.112 / 0.0050 / 0.0058 / 0.0138; at sigma = 0
    predicted 0.020 / 0.030 / 0.0075 / 0.0031, tilt 0.086 / 0.0041 / 0.0057 / 0.0050 (the
    outdoor worlds 3, 5 better, the indoor 16-beam ones 1, 7 worse). Lidar worlds 1-19
    odd, 150 epochs, rotation rms median deg (median / worst x the oracle): at 6 mm
    predicted 0.0116 (21 / 133), all 0.031 (34 / 242), tilt 0.0157 (27 / 129); at 2 cm
    0.0156 (11 / 40), 0.049 (27 / 181), 0.020 (11 / 42); ATE 14.5x / 46x / 25x (6 mm),
    7.7x / 32x / 8.5x (2 cm). Tilt: outdoor worlds better (6 mm: world 3 0.029 -> 0.0049
    deg, 11 0.0034 -> 0.0011, 15 0.0105 -> 0.0043, 17 0.022 -> 0.0062), the indoor 16-beam
    ones worse (1 0.015 -> 0.072, 13 0.0052 -> 0.055, 19 0.013 -> 0.111)."""
    deskew_rate_tolerance_deg_s: Positive = 0.5
    """Re-extract when the epoch's own angular rate differs from the one it was deskewed
    with by more than this, deg/s (0.5 deg/s smears a point 20 m away by 1.7 cm at 10 Hz;
    one epoch's rotation is far more precise)."""
    deskew_speed_tolerance_mps: Positive = 0.5
    """Likewise for the linear velocity, m/s; larger than the noise of one epoch's
    velocity (a few cm per epoch at 6 mm), whose smear does not grow with range."""
    deskew_significance_gate: bool = False
    """Streaming: deskew only with what an epoch's step measured beyond its noise: the
    rotation (3 DoF) and the horizontal translation (2 DoF) of the step are each taken as
    zero where they are within the chi-square 95 % bound of zero given the step's 5-DoF
    covariance, both for the re-extraction with the epoch's own twist and for the twist
    predicted for the next epoch (:func:`planodom.odometry.twist_refine.significant_twist`).
    Measured on nebula's parked test scans with per-point times (5 scans each, the car
    still): a step's noise deskewed the next extractions (a Hesai QT64's first step,
    9 cm of noise, re-extracted as 1.28 m; steps 127.8/41.1/5.2/3.0 cm, with the gate
    9.1/4.6/11.1/1.8 cm; a Pandar40P's 23.8/16.2/20.2/2.2 -> 3.3/3.1/4.2/9.7 cm). Off by
    default: on issue 11's lidar worlds 1-7 (100 epochs, 6 mm and 2 cm) it changes only
    world 1 (indoor, 16 beams), rotation rms 0.0166 -> 0.0185 deg at 6 mm and 0.0212 ->
    0.0230 deg at 2 cm, ATE 5.9 mm either way; KITTI 0005 (no point times) unchanged. On
    the 2D rig it is harmful (worlds 0-18 even, 150 epochs: world 0 at 6 mm ATE 0.27 ->
    3.08 m, world 2 at 2 cm 1.19 -> 10.1 m; median rotation 0.146 -> 0.204 deg at 2 cm):
    a twist within the noise of one step still smears a 2D scanner's sweep. For a lidar
    recording with stops, turn it on."""
    deskew_passes: Annotated[int, Field(ge=0, le=5)] = 0
    """Runs over a sequence (``run_odometry``) of scans with point times: after the
    streaming pass, run the odometry this many times on the scans deskewed to the middle
    of their epochs along a curve through the poses of the pass before (epochs on both
    sides, :func:`planodom.odometry.run.redeskewed_run`), then once more deskewed to the
    epoch times; 0: the streaming pass only. Each pass costs about half the streaming
    one (one extraction per epoch). Off by default: measured over 300 epochs at sigma = 0,
    two passes take the median per-epoch rotation error from 0.016 deg to 4e-5 deg (paper
    loop, urban canyon) and 4e-4 deg (issue 11's world), and at 6 mm by about a third on
    that world, but at 2 cm they interpolate the poses' noise: rms rotation error 0.36
    against 0.28 deg there (a fit weighing the poses' covariances would be needed)."""
    deskew_pass_guard: Literal["streaming", "consistent", "off"] = "streaming"
    """The passes' result per epoch (``deskew_passes`` > 0): "streaming", kept only where the last
    pass converged: the epoch was deskewed along the curve, its status is not worse than in the
    streaming pass, and its step agrees with the curve's within ``deskew_rate_tolerance_deg_s`` and
    ``deskew_speed_tolerance_mps`` (as rates over the step); elsewhere the streaming pass's estimate
    (:mod:`planodom.odometry.splice`: where the poses are off, the curve through them deskews the
    scans wrongly); "off": the passes' result everywhere; "consistent": "streaming" without a switch
    of run at an epoch the runs place differently (``splice.consistent``). Measured on issue 11's
    worlds 0-9, 100 epochs, 2 passes (interpolate), median over the 5 2D-rig worlds of the per-epoch
    rotation rms (deg), streaming / "off" / "streaming": 0 mm 0.122 / 0.276 / 0.117, 6 mm 0.208 /
    0.225 / 0.174, 2 cm 0.143 / 0.221 / 0.097 (no world above 1.08x the streaming pass, against
    4.1x); on the 5 lidar worlds the gains stay (0.0162 / 0.0026 / 0.0026 at 0 mm, 0.0199 / 0.0146 /
    0.0146 at 2 cm), the worst world (64 beams, its first and last epochs) 1.3-1.7x the streaming
    pass against 3.7-5.5x."""
    deskew_order: Literal[1, 3, 5] = 3
    """Degree of the polynomial (in the tangent space of a node's pose) through the
    ``deskew_order + 1`` nearest nodes that the passes deskew along. 3: converges in a
    couple of passes; 5 reaches a lower floor (sigma = 0, paper loop: 2e-5 against
    1.3e-4 deg rms) but needs about twice the passes."""
    deskew_fit: Literal["interpolate", "weighted", "increments"] = "interpolate"
    """The passes' curve: "interpolate", the polynomial through the ``deskew_order + 1``
    nearest nodes (exact at the nodes: it follows their noise); "weighted", the weighted
    least-squares polynomial of degree ``deskew_order`` over the nodes within
    ``deskew_fit_span_s`` (at least ``deskew_order + 2``), each tangent component of a
    node weighted by the inverse variance of the odometry's steps beside it (an
    unresolved step: not used), :func:`planodom.odometry.interpolate.curve_poses`;
    "increments", the same fit to the increments between the nodes (whose errors, unlike
    the chained poses', are independent), :func:`planodom.odometry.interpolate.
    increment_fit_weights`. Measured on issue 11's worlds 0-9, 100 epochs, median over the
    5 2D-rig / 5 lidar worlds of the per-epoch rotation rms (deg), streaming / 2 passes
    "interpolate" / 2 passes "increments" (degree 3, 0.5 s): sigma = 0: 0.122 / 0.276 /
    0.133 and 0.0162 / 0.0026 / 0.0050; 6 mm: 0.208 / 0.225 / 0.127 and 0.0166 / 0.0029 /
    0.0054; 2 cm: 0.142 / 0.221 / 0.473 (22 / 17 / 40 epochs unresolved) and 0.0199 /
    0.0146 / 0.0111 (lidar ATE 5.0 / 5.3 / 2.0 mm). So on lidars the passes help at every
    level (the fit most at 2 cm), but not on the 64-beam world without point times (its
    first epochs), and on the 5 Hz 2D rig at 2 cm every curve loses epochs; the fits miss
    the simulated routes' kinks of turn rate, so 1 s windows were worse everywhere."""
    deskew_fit_span_s: Annotated[float, Field(gt=0, le=5, allow_inf_nan=False)] = 0.5
    """A least-squares ``deskew_fit``: the time its window spans, s (one node per epoch, at
    least ``deskew_order + 2``). From the vehicle, not a world: the polynomial must follow
    the motion over the window, and a car's turn rate and its suspension's roll and pitch
    (0.2-0.7 Hz sway in the simulator, a quarter period of 0.35-1.2 s) change within a
    second; a wider window averages more noise down but misses more of that change
    (measured: 1 s worse than 0.5 s at every noise level, see ``deskew_fit``)."""
    twist_sigma: Literal["lost", "always", "fixed"] = "lost"
    """Streaming: how far off the twist an epoch is deskewed with is taken to be (the 2D-rig
    extraction widens its tolerances by the smear that leaves, ``extraction.
    twist_rate_sigma_deg_s`` / ``twist_speed_sigma_mps``). ``per_epoch``: from the model
    in :mod:`planodom.odometry.twist_sigma` (large for a predicted or held twist, small
    for one refined from the epoch's own estimate), never below the extraction's values.
    ``lost``: only when the extraction with the extraction's values leaves the epoch
    unresolved or with far fewer planes than the one before (then the better of the two is
    kept); ``always``: every extraction with a twist; ``fixed``: never (the extraction's
    values). Measured: see :func:`planodom.odometry.twist_sigma.widened_if_lost`."""
    rescue_gate: Literal["degenerate", "rate", "twist", "off"] = "degenerate"
    """Streaming, ``twist_sigma: lost``: a widened extraction replaces the epoch's own only
    when its twist agrees with the constant-velocity prediction within the predicted twist
    sigma and its step's error (chi2 at ``rescue_gate_quantile``, :meth:`planodom.odometry.
    twist_sigma.TwistUncertainty.consistent`). Widening admits other points into a plane,
    which can tilt the step and make a wrong one that the bridge then carries (issue 11's
    world 6 at 6 mm, epoch 51: degenerate, 5.3 deg/s off a rate predicted to 1.1 deg/s).
    ``rate``: the angular rate (3 DoF); ``twist``: the velocity too when the step measured
    it (3 more); ``degenerate``: the rate of a degenerate step only; ``off``: no gate.
    ``degenerate`` by default: an OK step has normals in three directions to check a tilted
    plane against, a degenerate one not; and the predicted twist's sigma misses what the
    prediction holds after a wrong or lost epoch in a changing turn (measured on the six
    worlds of issue 11, 150 epochs: ``rate`` rejected a right OK rescue 28 deg/s off a
    prediction held over two lost epochs, world 2 at 6 mm; ``twist`` right ones 3-5 sigma
    off in velocity, a median over ``velocity_window`` lagging an acceleration, world 8 at
    6 mm: ATE 0.23 -> 0.70 m)."""
    rescue_gate_quantile: Annotated[float, Field(gt=0, lt=1)] = 0.999
    """The chi2 quantile of ``rescue_gate`` and ``degenerate_gate`` (as ``smoothing.
    loop_gate_quantile``)."""
    degenerate_gate: Literal["bridge", "off"] = "bridge"
    """Streaming (pairwise pipelines, not the plane map): every degenerate step, from the
    epoch's own extraction or a rescue, is checked as ``rescue_gate: degenerate`` checks a
    rescue (its angular rate against the constant-velocity prediction, :meth:`planodom.
    odometry.twist_sigma.TwistUncertainty.consistent`). ``bridge``: one that disagrees is
    reported unresolved (``RelativePose.inconsistent``, the ``inconsistent`` column of
    epochs.csv) and bridged by constant velocity, as the solver's unresolved steps are: a
    degenerate step has no second normal direction to check its rotation against (issue
    11's world 6 at 2 cm, epoch 113: 192 deg/s against 12 true, from the epoch's own
    extraction). The prediction's rate sigma counts the rate's change across degenerate
    steps too (:meth:`planodom.odometry.twist_sigma.TwistUncertainty.gate_change`).
    ``off``: not checked. ``bridge`` by default: measured on issue 11's even worlds 0-10,
    150 epochs (rot deg / ATE m, off -> bridge): at 2 cm world 6 1.71 / 3.90 -> 0.42 /
    1.53, world 2 0.54 / 1.63 -> 0.52 / 1.19, world 10 0.17 / 0.27 -> 0.15 / 0.26, world
    0 0.11 / 0.68 -> 0.11 / 0.79; at 6 mm world 2 0.78 / 0.39 -> 0.71 / 0.25, world 6
    0.24 / 0.67 -> 0.37 / 0.75 (each step it bridged there was off the truth); the rest
    unchanged."""
    velocity_window: Annotated[int, Field(ge=1)] = 5
    """Streaming: the predicted linear velocity is the median over this many recent
    measured steps (the angular rate is the last step's)."""
    map_trend_rescue: bool = True
    """Streaming, plane-map pipeline: when the epoch deskewed with the predicted twist is
    suspect (not OK, or far fewer planes than the epoch before), extract it again with the
    twist extrapolated along the trend of the recent twists (:func:`planodom.odometry.
    trend.trend_twist`) before trying it without deskewing: the prediction, the mean of
    the last ``velocity_window`` twists, lags a turn that tightens by half the window.
    Measured on issue 11's lidar worlds 3, 5, 7, 9 (300 epochs, 6 mm and 2 cm): world 9
    (a tightening turn, 13 deg/s predicted for 23) ATE 0.55 / 0.69 -> 0.033 / 0.036 m,
    rotation 0.060 / 0.071 -> 0.022 / 0.024 deg rms, no epoch unresolved; the other
    worlds identical (no epoch there was suspect). The trend as the prediction of every
    epoch instead: ATE better on all four, but rotation rms worse on world 7 (0.0072 ->
    0.013 deg at 6 mm: a prediction within the deskewing tolerances is not refined)."""
    pairwise_trend_rescue: bool = False
    """Streaming, pairwise pipelines (the 2D rig's): an epoch still lost (unresolved, or
    far fewer planes than the epoch before) once the predicted twist, none and the held
    one were tried, is extracted again with the angular rate extrapolated along the trend
    of the recent measured rates (:func:`planodom.odometry.trend.pairwise_trend`; the
    velocity stays the prediction's): the prediction, the last step's rate, lags a turn
    that tightens, and deskewed with it a far wall tilts and gives a wrong rotation that
    ``degenerate_gate`` bridges (issue 11's world 6 at 6 mm, epoch 51: 12.1 deg/s
    predicted for 13.4, a wall 75 m away tilted 1.6 deg, the rotation 1.1 deg off; with
    exact deskewing the same solver is 0.01 deg off). Off by default, not yet better
    everywhere; measured on the even 2D-rig worlds, 300 epochs (rot deg / xy cm / ATE m
    / unresolved / gap*, off -> on): at 6 mm world 6 0.294 / 7.2 / 1.07 / 9 / 4 -> 0.244
    / 6.7 / 1.52 / 10 / 3, world 0 0.145 / 2.3 / 0.25 / 4 / 2 -> 0.149 / 2.9 / 0.44 / 4
    / 1 (a degenerate stretch kept a stale velocity median where an unresolved epoch had
    cleared it), the others identical; at 2 cm world 6 0.474 / 16.1 / 7.56 / 36 / 3 ->
    0.713 / 19.1 / 3.92 / 28 / 6, world 2 0.582 / 10.0 / 0.99 / 12 -> 0.542 / 8.7 / 0.93
    / 11, world 0 0.192 / 7.5 / 1.32 / 5 -> 0.181 / 7.3 / 1.13 / 1, world 16 0.476 /
    5.46 -> 0.496 / 5.53, worlds 12, 14, 18 within a few per cent, 4, 8, 10 identical.
    Tried on every suspect epoch (degenerate ones too), it was worse (world 6 at 6 mm:
    ATE 1.07 -> 2.90 m): the plane count picked other twists than the epoch's own rate."""
    reference_refresh_guard: bool = False
    """Streaming, pairwise pipelines: a reference epoch that was never deskewed (the first,
    or one kept as extracted without a twist) is extracted again with the next epoch's
    refined twist (:mod:`planodom.odometry.deskew`, step 2), and the next epoch's estimate
    against the new planes is kept even when its status is worse (the one against the old
    planes refers to planes that are gone). True: then the old planes are brought back
    instead, the estimate against them kept, and the epoch not extracted again. The next
    epoch's twist need not fit the reference's scan: on issue 11's worlds at 2 cm (2D rig)
    the reference lost walls or its ceiling that way and the next epoch was unresolved
    (world 6: the ground alone left, every few epochs of a straight stretch; world 2,
    epoch 64: two parallel corridor walls left of four planes). Off by default, not yet
    better everywhere (a measured epoch's error replaces a bridge's, and the runs at 2 cm
    are chaotic); measured on the even 2D-rig worlds, 300 epochs (rot deg / xy cm / ATE
    m / unresolved / gap*, off -> on): at 2 cm world 6 0.474 / 16.1 / 7.56 / 36 / 3 ->
    0.485 / 14.1 / 5.05 / 18 / 5, world 2 0.582 / 10.0 / 0.99 / 12 / 3 -> 0.476 / 6.3 /
    3.75 / 6 / 1, world 12 0.358 / 13.9 / 5.58 / 7 -> 0.687 / 14.5 / 4.88 / 10, world 10
    0.164 / 8.3 / 0.65 / 8 -> 0.210 / 8.5 / 1.61 / 1, world 16 0.476 / 5.5 / 1.01 / 6 ->
    0.155 / 3.6 / 0.91 / 2, world 0 slightly better; at 6 mm world 6 0.294 / 7.2 / 1.07 /
    9 / 4 -> 0.335 / 11.4 / 3.76 / 9 / 3, world 2 0.531 / 5.6 / 0.82 / 5 -> 0.472 / 4.1 /
    1.22 / 4, world 18 0.437 / 7.5 / 2.00 / 1 -> 0.361 / 6.6 / 1.83 / 0, worlds 0 and 8
    within a few per cent. Over 30 worlds at 150 epochs: docs/RESULTS.md (REFGUARD)."""
    first_epoch_reextract: Annotated[int, Field(ge=0, le=5)] = 0
    """Streaming, scans with point times: once the second epoch's step is measured, extract
    the first epoch again with that step's own twist and estimate the step again (the
    second epoch extracted with the same twist), this many rounds, each kept while the step
    stays measured and no worse (:mod:`planodom.odometry.first_epoch`; 0: the deskewing
    policy's single refresh only). Off: one step cannot tell the first epoch's twist from
    the second's (see the module), and measured with 3 it is mixed: generalisation worlds
    0-19, 150 epochs, 2D rig median ATE 0.149 -> 0.140 m at 6 mm (world 16 0.021 -> 0.030,
    world 10 0.066 -> 0.070) and 0.430 -> 0.429 m at 2 cm (world 2's rotation 0.52 -> 1.02
    deg, world 12 0.047 -> 0.064 m), lidars within a tenth of a millimetre; one lap with
    loops (batch+loops) median ATE 0.0133 -> 0.0120 m at 6 mm, 0.0505 -> 0.0531 m at 2 cm
    (world 16 0.021 -> 0.041 m), world 18 unchanged (its first step is degenerate: no
    velocity); quick start ATE 0.071 -> 0.076 m (xy 0.052 -> 0.050)."""
    pairwise_reference_time: Literal["epoch", "middle"] = "epoch"
    """``planemap.reference_time`` for the pairwise pipelines (the 2D rig's): ``epoch`` or
    ``middle``; measured in :mod:`planodom.odometry.planemap.midtime` (off: 6 mm ATE mixed)."""
    map_twist_offset: bool = False
    """Streaming, plane-map pipeline: the epoch's own twist (what it is extracted again
    with) has the offset its and the previous epoch's deskewing put in the step taken off
    (:func:`planodom.odometry.deskew.twist_offset`, as for the pairwise pipelines), and
    is used as it is; off: the mean of the twist used and the step's own (see
    :func:`planodom.odometry.deskew.register_deskewed`, ``against_map``). The deskewing
    twist dominates the lidar rotation error (issue 11, 150 epochs at 6 mm, rotation rms
    deg: deskewed along the true motion, world 3 / 9 / 15: 0.029 -> 0.0024, 0.026 ->
    0.0047, 0.0105 -> 0.0033; with the true constant twist of each sweep 0.0052, 0.0085,
    0.0047; segmented by the true labels, no better). Measured on the lidar worlds 3, 5,
    7, 9, 15 (300 epochs, 6 mm / 2 cm): rotation rms better on the worlds with recorded
    point times (7: 0.0072 / 0.0096 -> 0.0061 / 0.0076, 9: 0.022 / 0.024 -> 0.015 /
    0.016, 15: 0.0117 / 0.0130 -> 0.0091 / 0.0105), but it oscillates on the two whose
    times come from the azimuth (3: 0.029 -> 0.040 deg, xy 0.09 -> 2.2 cm; 5 at 6 mm:
    ATE 0.009 -> 0.21 m). With that twist still averaged with the one used (damped;
    not a setting), 6 mm: world 3 0.029 -> 0.026 deg (xy 0.088 -> 0.060 cm), 5 0.0093
    -> 0.0095, 9 0.022 -> 0.023: no oscillation, and no gain on world 9. Off until the
    oscillation is understood."""
    map_twist_lead: Literal["off", "rate", "twist"] = "rate"
    """Streaming, plane map with each sweep registered at its middle (``planemap.
    reference_time: middle``): the epoch's own twist, the mean over its step between the
    sweeps' middles (the twist half an epoch before this sweep's middle), led by half an
    epoch along its change since the previous epoch's own (:func:`planodom.odometry.trend.
    led_twist`) before the epoch is extracted again with it. "rate": the angular rate;
    "twist": the velocity too (when both steps measured it); "off": not led. Why: on issue
    11's lidar worlds 1 / 3 / 5 / 9 (150 epochs, 6 mm) the twist each epoch was finally
    deskewed with was off its sweep's true constant twist by 0.80 / 0.59 / 0.23 / 1.00
    deg/s rms, nearly all of it that lag (true step twist against the sweep's: 0.69 / 0.58
    / 0.16 / 0.95; the own twist's noise 0.14 / 0.06 / 0.03 / 0.07 deg/s; the velocity
    0.03-0.13 m/s off, the prediction's, never refined within ``deskew_speed_tolerance_mps``).
    Deskewed with each sweep's true constant twist, rotation rms 0.0049 / 0.0055 / 0.0030
    / 0.0071 -> 0.0038 / 0.0038 / 0.0013 / 0.0052 deg: the twist no longer dominates (the
    oracle: about 0.0003). Measured (``planodom experiment generalisation --worlds 20 --rig
    lidar --noise 0.006 0.02 --epochs 150``, 10 lidar worlds; "rate", ``map_lead_*``
    defaults): median rotation rms 0.00376 -> 0.00327 deg at 6 mm (5.8 -> 5.8x the oracle,
    worst 50 -> 31x), 0.00789 -> 0.00675 at 2 cm (5.1 -> 4.8x, worst 15.4 -> 10.6x); ATE
    1.01 -> 0.63 mm (4.5 -> 2.9x), 2.45 -> 1.91 mm (3.5 -> 2.8x); world 17 0.0127 -> 0.0038
    deg, 5 0.0030 -> 0.0013; epochs/s 26.2 -> 25.7, 22.2 -> 19.4. Off until LIDARROT, some
    worlds worse: world 9's ATE at 6 mm 1.12 -> 1.69 cm (rotation 0.0071 -> 0.0060 deg), 19's
    at 2 cm 1.43 -> 1.90 mm, 11's 0.66 -> 0.83 mm (rotation at 6 mm 0.0009 -> 0.0011 deg),
    7's rotation at 2 cm 0.0064 -> 0.0070 deg. With the general tolerances (0.5 deg/s, 0.5
    m/s, 2 iterations) it gains a third as much (6 mm, worlds 1 / 3 / 5 / 9: 0.0044 / 0.0049
    / 0.0028 / 0.0063 deg); "twist" is worse than "rate" (the own velocity's noise, 0.01-0.03
    m/s, is as large as its lag, 0.005-0.017). Again on the lidar worlds 1-39 (odd, 300
    epochs; 21-39 held out), against the defaults of ``extraction.viewpoint_planes:
    ransac``: median rotation 0.0037 -> 0.0028 deg at 6 mm (held out 13.6 -> 8.9x the
    oracle; world 23 0.037 -> 0.011), 0.0066 -> 0.0057 at 2 cm, ATE 1.53 -> 1.29 and 2.83
    -> 2.11 mm; but world 33's ATE at 6 mm 1.5 -> 280 mm, world 9's 15 -> 33 mm, world 31's
    at 2 cm 20 -> 51 mm. The default, shrunk (``map_lead_shrink``), since LIDARROT."""
    map_lead_rate_tolerance_deg_s: Positive = 0.2
    """``map_twist_lead`` on: replaces ``deskew_rate_tolerance_deg_s``. Worlds 1 / 3 / 5 / 9,
    150 epochs, "rate", rotation rms deg at 6 mm and 2 cm: 0.1: 0.0047 / 0.0040 / 0.0010 /
    0.0042 and 0.0149 / 0.0065 / 0.0101 / 0.0063 (world 5 at 2 cm: an own vertical velocity
    1 m/s off, deskewed with, the steps after it wrong); 0.2: 0.0048 / 0.0041 / 0.0013 /
    0.0060 and 0.0150 / 0.0067 / 0.0026 / 0.0069; off: 0.0049 / 0.0055 / 0.0030 / 0.0071
    and 0.0145 / 0.0072 / 0.0032 / 0.0086."""
    map_lead_speed_tolerance_mps: Positive = 0.05
    """``map_twist_lead`` on: replaces ``deskew_speed_tolerance_mps``. 0.5 (the prediction's
    velocity stays; 10 lidar worlds as in ``map_twist_lead``): world 17 at 6 mm 0.0127 deg
    against 0.0038; medians 0.00333 / 0.00660 deg; ATE worse at 2 cm on worlds 1 and 13."""
    map_lead_iterations: Annotated[int, Field(ge=0, le=10)] = 3
    """``map_twist_lead`` on: replaces ``deskew_iterations`` (2, at 0.1 deg/s: worlds 3 / 9
    at 6 mm 0.0054 / 0.0061 deg against 0.0040 / 0.0042 with 3)."""
    epoch_period_s: Positive = 0.1
    """Epoch period used when epochs come without times, seconds."""
    min_sigma_rotation_deg: Positive = 0.001
    """Floor of the reported per-axis rotation sigma, degrees."""
    min_sigma_translation_m: Positive = 0.0005
    """Floor of the reported per-axis translation sigma, metres."""
