"""Configuration of the plane-map odometry (``odometry.pipeline: map``).

Every default says where it comes from: sensor physics, a datasheet, a rule of the
estimator, or "measured on KITTI 0005" (the one recorded drive it was developed on; such
values were not tuned on any other recording and are marked so).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import ConfigDict, Field

from planodom.config.few_inliers import FewInliersConfig

Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]


class PlanemapConfig(FewInliersConfig):
    """The plane-landmark odometry against a local plane map
    (:mod:`planodom.odometry.planemap`)."""

    model_config = ConfigDict(allow_inf_nan=False)

    laser_bias_m: float = Field(0.02, ge=0, le=1)
    """Per-laser range bias sigma (m), constant along one scan line: the datasheet range
    accuracy (Velodyne HDL-64E <= 2 cm; VLP-16 and Ouster OS1 about 3 cm). A plane's
    information then grows with the scan lines it spans, not with its points. On KITTI
    0005 0.01 / 0.02 / 0.03 gave 0.138 / 0.079 / 0.077 deg rms (the term also absorbs map
    lag and scan skew); 0 makes every gate too tight (all epochs lost). With
    ``laser_bias: fitted``, the upper bound of the fitted bias."""
    deskew_variance: Literal["off", "twist_change"] = "off"
    """The registration's variances of a scan's planes: ``off``, the point noise and the
    laser bias; ``twist_change``, plus what the deskewing twist's error does to each
    plane through its own first-order change with the twist (``Plane.deskew_jacobian``,
    switched on in the extraction), the error's covariance per axis the mean square of the
    constant-velocity model's deviations so far (rotation and translation over 3, per
    epoch span: the change of motion from one epoch to the next, as
    ``smoothing.deskew_noise: twist_change_jacobian`` takes it; cautious, as the final
    twist's lag is about half of it). A plane swept while the twist was off is tilted and
    moved by it; a scan plane seen in an instant is not. Measured (the ten lidar worlds of
    ``planodom experiment generalisation --worlds 20 --rig lidar --epochs 300``, off ->
    twist_change, medians): 6 mm rotation 0.0037 -> 0.0034 deg (worst 51x -> 45x the
    oracle), ATE 1.32 -> 0.90 mm, better on worlds 1, 3, 5, 7, 9, 17 (world 9 0.0068 ->
    0.0039 deg), worse on 11 (0.0010 -> 0.0012 deg) and the ATE of 15 (0.63 -> 1.40 mm)
    and 19 (0.46 -> 0.56 mm); 2 cm rotation 0.0075 -> 0.0077 deg, ATE 3.0 -> 3.2 mm,
    rotation worse on worlds 1, 3, 5, 11, 13, 15, 19 (13: 0.021 -> 0.028 deg), ATE on 1,
    3, 11, 17 (3: 1.6 -> 5.0 mm), better on 9 (0.0082 -> 0.0063 deg). At sigma 0 (150
    epochs) world 3 / 9 0.0052 / 0.0073 -> 0.0043 / 0.0040 deg. KITTI raw 0005 (no point
    times, no Jacobians) unchanged. Off: mixed at 2 cm, where the deviations it is scaled
    by also hold the odometry's own noise."""
    twist_estimation: Literal["none", "registered", "registered_acceleration"] = "none"
    """Whether a scan's own twist is measured in its registration against the map
    (continuous time, :mod:`planodom.odometry.planemap.ctreg`; needs point times, and
    switches on ``extraction.time_moments``): ``none``, the scan is registered with the
    twist it was deskewed with (predicted from the steps before: it lags the sweep);
    ``registered``, after the registration a Gauss-Newton over the inlier associations
    solves the pose and a correction of the deskewing twist together, from each plane's
    time-weighted moments (the exact point-to-plane cost of the points moved by the
    correction); the corrected twist is the epoch's own twist (what it is extracted again
    with, :func:`planodom.odometry.deskew.register_deskewed`) and the next epoch's
    prediction; ``registered_acceleration``, also the twist's rate of change within the
    sweep (moments up to ``t^4``), which the next epoch's prediction extrapolates by
    (the deskewing itself stays a constant twist). Scans without point times are
    unchanged. Measured ``registered_acceleration`` against the default (full runs,
    planodom only): hand-held worlds 40-47 (150 epochs) rotation geometric-mean ratio
    1.02 at 6 mm (better on 5 of 8), 1.23 at 2 cm (4 of 8); ATE 0.82 / 1.03 (4 / 3 of 8
    better); better on the 32- and 64-beam worlds (41 6 mm ATE 0.046 -> 0.023 m, 45
    11.9 -> 0.40 m), worse on the 16-beam 20 Hz worlds 44 and 46 (44 6 mm 0.27 -> 1.44
    deg, 46 0.21 -> 0.45 deg: few planes, the twist and its change poorly observed).
    Vehicle lidar worlds 1-39 odd (300 epochs): rotation ratio 1.66 at 6 mm (4 of 20
    better), 1.11 at 2 cm (4 of 20); ATE 1.47 / 1.23; worlds 41-59 odd: rotation 2.05 /
    1.32, ATE 1.53 / 1.31. At sigma 0 it helps (world 1, 60 epochs: 0.0063 -> 0.0036 deg
    with ``registered``), at 6 mm its per-scan twist noise costs more than the lag it
    removes. Hence off. KITTI raw 0005 (no point times) byte-identical."""
    twist_filter: Literal["off", "kalman"] = "off"
    """With ``twist_estimation``: ``off``, each scan's registered twist is its own;
    ``kalman``, a Kalman filter on the twist and its rate
    (:mod:`planodom.odometry.planemap.twist_filter`) fuses each scan's step from the last
    registered pose (its mean twist: precise, half a step late) with its registered
    twist (current, noisier; its covariance scaled until its innovations' median is
    chi-square's, gated at the 99.9 % point); the rate's random walk is estimated from
    the steps' innovations, not set. The filter's prediction is the registration's
    prior on the twist correction; its posterior the epoch's twist (extracted again
    with) and, carried on by its rate, the next epoch's deskewing twist. Measured with
    ``registered_acceleration`` (60 epochs, planodom only; geometric means of the
    per-world ratios to the default, 6 mm / 2 cm): hand-held worlds 40-47 rotation rms
    1.04 / 1.28, ATE 0.72 / 1.15 (``registered_acceleration`` alone 0.76 / 1.07, ATE
    0.61 / 0.83); worse on the 16-beam 20 Hz worlds 44 and 46 (44 at 6 mm 0.20 -> 0.99
    deg, its registered poses' steps themselves 23 deg/s off in yaw) and at 2 cm on
    world 47 (lost in every configuration: 18 -> 33 deg); vehicle lidar
    worlds 1-9 odd rotation 1.10 / 1.01, ATE 0.74 / 0.87 (alone 1.09 / 1.09, 0.65 /
    0.82); 41-49 odd rotation 1.17 / 1.09, ATE 0.83 / 1.03 (alone 1.61 / 1.13, 1.11 /
    0.99). Against the simulator's true twist (60 epochs, 6 mm) its yaw-rate error is
    0.52 deg/s on vehicle world 1 (the registered twists alone 7.5) and 2.6 deg/s on
    hand-held world 41 (alone 7.8, NEES 5.4 where 6 is expected). Not better than the
    default in rotation overall: off."""
    twist_map_update: Literal["deskewed", "corrected"] = "corrected"
    """With ``twist_estimation``: the map is updated with the scan's planes as deskewed
    (``deskewed``) or moved by the twist correction its registration measured, from
    their time moments (``corrected``; the epoch is usually extracted again with the
    corrected twist anyway, but not when the correction is within the deskewing
    tolerances)."""
    laser_bias: Literal["fixed", "fitted"] = "fixed"
    """Where the registration's laser bias comes from (:mod:`planodom.odometry.planemap.bias`):
    ``fixed``, ``laser_bias_m``; ``fitted`` (experimental), fitted to each scan's
    registration residuals (variance components by the median: the bias at which the
    associations' median whitened residual is that of a right model), between 0 and
    ``laser_bias_m``, and used for the next scan and the map. The bias sets the planes'
    relative weights: with 2 cm a plane's information grows with its scan lines, without
    bias with its points. It is the procedural lidars' second floor (issue 11; their range
    noise has no per-laser bias): substituting the truth one stage at a time (150 epochs,
    6 mm, rotation rms per epoch), with the points deskewed along the true motion the
    default leaves world 1 / 3 / 9 at 0.0065 / 0.0023 / 0.0026 deg (oracle 0.0024 /
    0.0003 / 0.0002), with a 0.1 mm bias 0.0032 / 0.0011 / 0.0004, and with one plane per
    true surface as well 0.0023 / 0.0003 / 0.0002: the oracle (known associations change
    nothing more; at sigma 0 both are exact). Fitted, on those truth-deskewed points:
    world 1 / 9 0.0031 / 0.0003 (world 3, 60 epochs: 0.0021 -> 0.0006), the fitted bias
    0 throughout. Not the
    default: the median fits 0 where most planes agree, and the few with larger errors
    (the deskewing twist's lag as run; an extraction's fragment) then become the kernel's
    outliers and are dropped: as run (150 epochs, 6 mm) world 9 lost track (ATE 11 mm ->
    6.2 m), world 1 0.0049 -> 0.0059 deg; with the offline passes
    (``odometry.deskew_passes: 2``: world 3 / 9 0.0020 / 0.0032 deg) too (0.014 / 0.015
    deg). On KITTI raw 0005 the lines' own offsets (per recovered row, against
    each plane) measure 5-7 mm where its fixed bias wants 2 cm (1 cm: 0.138 deg); fitted,
    its RPE is 0.0868 -> 0.0858 deg, 3.59 -> 3.60 cm."""
    memory_scans: float = Field(5.0, ge=0)
    """Time constant (scans) of the exponential fading of landmark moments; 0: no fading.
    Old observations carry the drift accumulated since. Measured on KITTI 0005 (best of
    3, 5, 7, 10, none: 0.099, 0.089, 0.091, 0.099, 0.118 deg): not tuned elsewhere."""
    max_age_scans: Annotated[int, Field(ge=1)] = 10
    """A landmark not seen for this many scans is dropped: two fading time constants
    (weight below e^-2)."""
    max_range_m: Positive = 120.0
    """Landmarks farther than this from the sensor are dropped (m): the longest range of
    common spinning lidars (HDL-64E 120 m)."""
    max_landmarks: Annotated[int, Field(ge=10)] = 2000
    """Most landmarks (the least recently seen go first): memory stays flat."""
    flat_sigmas: Positive = 3.0
    """A plane joins its landmark only while the merged moments stay flat: RMS to the
    refit plane within this many point sigmas (the extraction's member_sigma_factor)."""
    min_rows: Annotated[int, Field(ge=1)] = 1
    """Scan planes spanning fewer scan lines than this (when their lines are known:
    ``PlaneSupport.n_rows`` above 0) are not used (neither registered nor mapped). A
    single line does not define a plane: its points lie on its laser's cone (range noise
    moves them along their rays, within it), and a near-level line across facades at
    several depths fits a thin level "plane" fixed to the sensor. At 2 cm, 60-80 of a
    64-beam scan's 100-150 planes were such lines on procedural world 29: registered
    against their own landmarks they held roll and pitch still (every epoch's tilt step
    estimated zero, error minus the ~0.2 deg sway) at ~0.01 deg claimed sigma, and, 1 mm
    thick, they set the scan's noise sigma to its floor. Measured with 2 (300 epochs,
    lidar worlds 1-39 odd, rotation rms per epoch; default from the same code): 2 cm
    median 0.0083 -> 0.0060 deg, ATE 3.1 -> 2.0 mm; world 29 0.190 -> 0.121, 27 0.032 ->
    0.0059, 13 0.021 -> 0.0064, 31 0.0086 -> 0.0047, 39 0.0087 -> 0.0035; worse 37 (lost
    either way: unresolved 53 -> 110) and 15 (0.0054 -> 0.0057), ATE of 9 17.7 -> 29.1 mm;
    6 mm median 0.0037 -> 0.0036 deg, worse on 29, 31 (0.0019 -> 0.0020) and 37 (110 ->
    163 unresolved). Not the default: KITTI raw 0005 RPE rotation 0.0868 -> 0.0962 deg
    (translation 3.59 -> 3.58 cm); there the lines' sensor-fixed "planes" stand for a
    tilt that hardly changes (a car on a flat road)."""
    min_inliers: Annotated[int, Field(ge=3)] = 6
    """An epoch is resolved with at least this many inlier planes (whether they fix every
    direction is judged from their information: ``unobserved_rotation_deg``,
    ``unobserved_translation_m``). 6 is one plane per degree of freedom, but a plane fixes
    up to three: a sparse lidar in a corridor (floor, ceiling, two walls, one far end
    wall) was left unresolved although its five planes fix the step. Measured 6 -> 4 (300
    epochs, lidar worlds 1-39 odd, 6 mm and 2 cm) before ``extraction.
    organised_window_deg``: only world 37 changed (indoor, 16 beams, no ring or time; 5-6
    planes an epoch in its corridors): 6 mm rotation rms 0.074 -> 0.017 deg, ATE 60 -> 2.3
    mm, unresolved 9 -> 0; 2 cm 0.087 -> 0.020 deg, 136 -> 3.9 mm, 18 -> 0. With that
    window (7-8 planes an epoch there) 4 changes nothing on worlds 5 and 37 and, of the
    others, only world 23 at 6 mm by 3e-4 of its figures (rotation 0.036766 -> 0.036776
    deg, ATE 0.9122 -> 0.9125 mm, xy 0.02497 -> 0.02493 cm); KITTI raw 0005's poses are
    byte-identical. Not measured better overall, so 6 stays."""
    min_inlier_fraction: float = Field(0.3, gt=0, le=1)
    """...and at least this fraction of the scan's planes inliers (a wrong prediction
    still lets a few planes, e.g. the ground, associate). Measured on KITTI 0005."""
    suspect_ratio: float = Field(0.7, gt=0, le=1)
    """A resolved epoch whose inlier fraction falls below this times the median of the
    last 20 epochs is suspicious: other hypotheses are scored too."""
    gn_iterations: Annotated[int, Field(ge=1)] = 6
    """Gauss-Newton iterations per association round (converges in 2-3 on KITTI)."""
    association_rounds: Annotated[int, Field(ge=1)] = 4
    """Rounds of association and Gauss-Newton (ICP's outer loop)."""
    cauchy_scale: Positive = 2.0
    """Cauchy kernel scale on an association's whitened residual (sigmas)."""
    outliers: Literal["dropped", "kernel", "deleted", "doubtful"] = "dropped"
    """What the registration does with the associations it ends with a Cauchy weight of
    at most 0.5 (the outliers the inlier counts and the map update already leave out):
    ``dropped``, solved again without them, until the set repeats
    (:func:`planodom.odometry.planemap.register.solve`); ``kernel``, kept with their small
    weight (before issue 11): the Cauchy kernel leaves every outlier a pull of ``c^2 /
    chi``, and on parked lidars a handful of wrong associations (fragments of curved
    surfaces a few metres away, through the wide gates of their ill-defined normals) moved
    the sensor along the one direction only they observe. A rule of the estimator, not
    tuned. Measured, kernel -> dropped: five parked lidars (tier4/nebula's test scans,
    true motion zero) largest step without / with point times QT64 23.6 / 127.8 -> 4.1 /
    5.8 cm, Pandar40P 6.6 / 23.8 -> 4.7 / 7.5, AT128 8.9 / 28.8 -> 8.4 / 5.9, XT32M 6.2 /
    5.1 -> 3.1 / 1.0, VLP-16 1.6 / 1.5 -> 1.2 / 2.5; a hand-held VLP-16 corridor walk, ATE
    against KISS-ICP 0.268 -> 0.250 m; the eight procedural lidar worlds (150 epochs, 6 mm
    and 2 cm) within +-0.1 cm of ATE; KITTI raw 0005 rotation 0.077 -> 0.087 deg rms
    (translation 3.58 -> 3.59 cm): there it drops a few true planes whose model is off
    (the cambered ground at chi 3-5), not wrong associations. ``deleted`` (not the
    default, experimental): one association at a time, the one with the largest deleted
    chi-square (its residual under the pose of the others and the prediction, whose
    per-axis variance is the gates' RMS deviation squared over 3) is dropped while that
    would give it a Cauchy weight of at most 0.5 (the kernel's own outlier definition: no
    other number) (:mod:`planodom.odometry.planemap.outliers`). Measured (full runs):
    KITTI 0005 rotation RPE 0.087 deg as ``dropped`` (its cambered ground patches are
    many, each of little leverage, so the deleted residual is the fitted one); parked
    largest steps
    without / with point times QT64 4.0 / 8.2 cm, 40P 9.3 / 9.2, AT128 8.4 / 6.6, XT32M
    3.1 / 1.9, VLP-16 1.2 / 6.3 (``dropped``: 4.1 / 5.8, 4.7 / 15.7, 8.4 / 4.3, 3.1 / 1.9,
    1.2 / 3.2): not better, hence not the default.
    ``doubtful`` (not the default): as ``dropped``, but only associations whose scan plane's
    normal sigma exceeds ``doubtful_normal_deg`` may be dropped; the others keep their
    Cauchy weight (a well-defined plane matched through the gates is that surface; its
    excess residual is the map's model error, as on a cambered road, and the kernel's
    down-weighting is the right treatment). Measured (full runs): KITTI 0005 rotation RPE
    0.087 -> 0.079 deg, translation 3.59 cm either way, ATE 1.39 -> 1.36 m; parked largest
    steps without point times as ``dropped``, with them QT64 5.8 -> 15.9 cm (one
    well-defined ceiling patch, 47 points over 8 lines, kept at chi^2 5 moved the first step
    4 -> 6 cm, and the deskew compounds it), 40P 15.7 -> 10.9, AT128 4.3 -> 2.2, XT32M and
    VLP-16 unchanged; a hand-held VLP-16 walk (replay) ATE against KISS-ICP 0.25 -> 0.32 m.
    Hence not the default."""
    tie_rule: Literal["distance", "likelihood", "informative"] = "distance"
    """Which of the landmarks that pass a scan plane's gates it is associated with
    (:func:`planodom.odometry.planemap.register.tie_cost`): ``distance``, the least mean
    squared distance of its points; ``likelihood``, the largest Gaussian likelihood of
    its distance and normal angle under the gates' variances (pose, plane and the
    landmark's own uncertainty at the plane), so that a stale, far, weak landmark of the
    same surface, whose extrapolated uncertainty lets it pass the gates, does not win
    over the live one by a millimetre of distance (generalisation world 75, 6 mm: the
    ground, 8310 points, tied to a 25-point ground landmark 35 m away, 7 vs 8 mm);
    ``informative``, the least distance among the landmarks that know the plane's
    offset at least as well as the prediction (offset variance at the plane at most
    the prediction's), the others only when no such landmark passes. Rules of the
    estimator, not tuned. Measured (generalisation, lidar worlds 1-19 and 61-79 odd, 150
    epochs, 6 mm / 2 cm, distance -> likelihood; docs/RESULTS.md "The tie rule"): ties
    to a same-surface landmark ten times less certain at the plane than another that
    passed (against the simulator's labels) 43 -> 2 on world 65 at 6 mm, 2 -> 0 on world
    75 at 6 mm; 40 runs, geometric mean of the per-run ratios rotation 0.98 / 0.93, ATE
    1.01 / 1.08, median ATE 1.41 -> 1.41 / 2.28 -> 2.61 mm; world 71 at 6 mm ATE 17.1 ->
    6.4 mm, but world 77 at 2 cm rotation 0.0066 -> 0.0157 deg, world 1 at 2 cm ATE 1.5
    -> 3.3 mm, 65 at 6 mm 0.48 -> 1.02 mm; KITTI raw 0005 rotation RPE 0.087 -> 0.069
    deg, translation 3.59 -> 3.64 cm, ATE 1.39 -> 1.43 m; hand-held 40-47 rotation
    better on 5 / 6 of 8, world 45 at 6 mm 2.1 -> 4.1 deg. ``informative``: rotation
    0.99 / 0.96, ATE 1.01 / 1.01, KITTI 0.088 deg, 3.61 cm, 1.35 m. Neither is no worse
    overall: ``distance`` stays the default."""
    doubtful_normal_deg: float = Field(1.0, gt=0, le=90)
    """``outliers: doubtful``: scan planes whose normal sigma (the bias model's, per axis)
    exceeds this may be dropped as outliers. Measured on KITTI 0005 and the five parked
    recordings (replays on cached planes), not derived: 1 deg keeps every parked step (no
    point times) as ``dropped`` and gives KITTI 0.079 deg; 2 deg KITTI 0.075 but Pandar40P's parked
    step 4.7 -> 7.7 cm; 3 deg 0.078 / 7.9 cm; 5 deg 0.076 / 10.8 cm (the parked wrong
    associations are fragments of 1-3 rows whose normal sigmas are several degrees)."""
    score_truncation: Positive = 3.0
    """Candidate poses are scored by the sum over all the scan's planes of their whitened
    point-to-plane residual to the best landmark, truncated at this many sigmas per
    residual (an unexplained plane costs the same whatever it is wrong by)."""
    max_tilt_change_deg: float = Field(60.0, gt=0, le=180)
    """Hypotheses that turn the base z axis by more than this between two scans are
    rejected: neither a vehicle nor a hand-held sensor tilts so much in one scan, while
    LDA's flips (a pair of walls matched to itself reversed) turn it by ~180 deg."""
    unobserved_rotation_deg: Positive = 1.0
    """A rotation direction with a larger 1-sigma (deg) is unobserved: when all are, the
    epoch is unresolved; when some are, see ``partial_rotation``."""
    partial_rotation: Literal["unresolved", "prediction"] = "prediction"
    """An epoch whose planes fix only part of the rotation (one plane family: the ground
    alone fixes roll and pitch, not yaw): ``unresolved``, bridged by constant velocity
    (before issue 14); ``prediction``, measured where observed, with the rotation about
    the unobserved axes the constant-velocity prediction's and its uncertainty (the RMS
    rotation deviation of the model), reported ``rotation_partly_observed``, as
    ``degenerate_translation: prediction`` does for translation. A rule of the estimator,
    not tuned; measured: the ten procedural lidar worlds (300 epochs, 6 mm and 2 cm) and
    KITTI raw 0005 have no such epoch and are bit-identical either way."""
    unobserved_translation_m: Positive = 0.1
    """A translation direction with a larger 1-sigma (m) is unobserved (the prediction is
    kept there): the epoch is degenerate, e.g. along a straight street where nothing but
    parallel facades and the ground are seen."""
    degenerate_translation: Literal["prediction", "registration"] = "prediction"
    """Where a degenerate epoch's unobserved translation directions (1-sigma above
    ``unobserved_translation_m``) come from: ``prediction``, the constant-velocity
    prediction, with the prediction's uncertainty (the RMS deviation of the model so far):
    the little information the planes give there (walls a degree apart along a corridor)
    is not a measurement, yet Gauss-Newton moves along it as far as it says (a hand-held
    VLP-16 corridor walk: 6.4 m in one epoch, 13 sigma off the prediction, where
    KISS-ICP moves 0.5 m); ``registration``: where Gauss-Newton ended (before issue 11).
    A rule of the estimator (the status's meaning), not tuned: OK epochs are unchanged."""
    degenerate_velocity: Literal["kept", "step"] = "step"
    """The constant velocity after a degenerate epoch (the next prediction, and the bridge
    of an unresolved epoch): ``step``, the degenerate epoch's own step; ``kept``, the last
    one not measured by a degenerate epoch (its rotation rests on the fewest planes, and
    bridging repeats it). ``kept`` is better on the still libwave garage (rotation rms
    0.217 -> 0.148 deg) but mixed on the hand-held lidar worlds, so off (docs/RESULTS.md,
    "A second real recording")."""
    kept_pose: Literal["registration", "reported"] = "reported"
    """The world pose an epoch keeps (its map update, the next prediction and twist) when
    its relative pose took part of itself from the prediction (an unobserved vertical
    with ``reference_time: middle``, a partly observed rotation): ``registration``,
    where Gauss-Newton ended (only a degenerate epoch's unobserved translation is the
    prediction's); ``reported``, the pose reported, prediction included. Generalisation
    world 75 (6 mm) tied its ground plane to a stale 25-point ground landmark whose
    extrapolated uncertainty left the vertical unobserved: the relative pose took the
    prediction's vertical, the kept pose Gauss-Newton's 0.36 m drift, the map's ground
    moved with it, the next prediction carried it and the next epochs went 10 m off
    vertically and 5 cm horizontally, every epoch "ok". Measured (generalisation, lidar
    worlds 1-19 and 61-79 odd, 150 epochs, ``registration`` -> ``reported``; runs where
    it never acts are bit-identical: 31 of 40, and KITTI raw 0005; on worlds 61 and 79
    at 6 mm it acts by a few millimetres, same figures): world 75 6 mm ATE
    95.1 -> 2.0 mm, xy 5.87 -> 0.36 mm, rotation 0.0073 -> 0.0034 deg; world 3 ATE 1.29
    -> 0.99 / 2.02 -> 1.98 mm (6 mm / 2 cm) but its 2 cm rotation 0.0072 -> 0.0079 deg;
    world 61 2 cm rotation 0.0058 -> 0.0063 deg (ATE 4.85 -> 4.81 mm); world 73 6 mm
    rotation 0.0014 -> 0.0015 deg, ATE 0.525 -> 0.534 mm; world 5 2 cm ATE 2.38 -> 2.46
    mm; world 75 2 cm ATE 2.21 -> 2.17 mm. Medians 6 mm ATE 1.56 -> 1.41 mm (mean 7.5 ->
    2.8, worst 95 -> 17 mm), rotation 0.0038 -> 0.0034 deg; 2 cm ATE 2.29 -> 2.28 mm,
    rotation unchanged (geometric mean of the ratios 1.009). Hand-held worlds 40-47, 60
    epochs, 6 mm and 2 cm: 12 of 16 runs bit-identical; world 40 at 6 mm rotation 3.08 ->
    2.43 deg, ATE 3.11 -> 1.10 m, at 2 cm 2.29 -> 2.58 deg, 0.45 -> 0.50 m; world 43 at 6
    mm 0.50 -> 0.72 deg, ATE 0.221 -> 0.213 m; world 47 at 6 mm 12.3 -> 15.3 deg, ATE 6.8
    -> 2.2 m (those worlds fail either way). ``reported`` is the default: a pose whose
    reported part came from the prediction must not carry, unreported, a drift along
    that part into the map and the next prediction (world 75's failure was silent, every
    epoch "ok"); the cost is up to 10 % of rotation on three of the 40 vehicle runs."""
    reference_time: Literal["epoch", "middle"] = "middle"
    """The time at which each scan is registered (:mod:`planodom.odometry.planemap.midtime`,
    in :func:`planodom.odometry.run.run_odometry`): ``epoch``, the epoch's time (a lidar
    stamped at the start of its sweep: the start); ``middle``, the middle of its points'
    times, the poses then brought back to the epoch times along the curve through them,
    and the epoch extracted again with its own twist as it is (not averaged with the one
    used: a twist error no longer shifts the scan as a whole). A twist that lags the
    sweep (it comes from the steps before) shifts a scan registered at its start by the
    error times the points' mean time. Applies only to scans with point times (given, or
    from a declared ``extraction.sweep``); pairwise: ``odometry.pairwise_reference_time``.
    Measured: the lidar worlds better in rotation, xy and ATE, KITTI raw 0005 2 % worse
    (figures in :mod:`planodom.odometry.planemap.midtime`)."""
    first_pose: Literal["quadratic_fit", "quadratic", "cubic", "mixed"] = "quadratic_fit"
    """With the sweeps registered at their middles (``reference_time: middle``, and the
    pairwise ``odometry.pairwise_reference_time: middle``), the curve the first epoch's
    pose at its epoch time, half a sweep before the first middle, is extrapolated on
    (:func:`planodom.odometry.planemap.midtime.first_pose`): ``quadratic_fit``, the
    least-squares quadratic over the first five middles; ``quadratic`` / ``cubic``, the
    polynomial through the first three / four. The run's first pose is the identity, so
    this error turns the whole run. Measured (150 epochs, figures in
    :func:`~planodom.odometry.planemap.midtime.first_pose`): the cubic is closer on 9 of
    the 16 hand-held walks (40-47, 6 mm and 2 cm), farther on 7; ATE worse on 15 of the
    20 vehicle lidar runs (1-19 odd, geometric mean of the ratios 1.56, the quadratic
    through three 1.35): ``quadratic_fit`` stays the default. ``mixed``: roll and pitch
    from the least-squares cubic over six, yaw and translation from the quadratic over
    seven (:func:`~planodom.odometry.planemap.midtime._mixed`; docs/RESULTS.md, LIDARACC)."""
    pass_reference_time: Literal["epoch", "middle"] = "epoch"
    """``odometry.deskew_passes`` with ``reference_time: middle``: ``middle``, every pass
    registered at the sweeps' middles, its curve through the last pass's poses there,
    then brought to the epoch times (:mod:`planodom.odometry.middle_passes`); ``epoch``,
    the last pass at the epoch times. docs/RESULTS.md, LIDARCURVE."""
    prediction: Literal["mean", "last", "trend"] = "trend"
    """The twist each epoch is first deskewed with (the streaming odometry's constant-
    velocity prediction, :func:`planodom.odometry.trend.predicted_twist`): "mean", the
    mean of the last ``odometry.velocity_window`` epochs' own twists; "last", the last
    epoch's own twist. The mean lags a turn or a sway by half the window, and a twist
    more than ``odometry.deskew_rate_tolerance_deg_s`` off is extracted again (on the
    indoor lidar worlds 1-2 deg/s off in most epochs: 2.2 extractions an epoch).
    Measured (lidar worlds 1-15 odd, 45, 57; 150 epochs, 6 mm and 2 cm; mean -> last):
    extractions an epoch 1.8-2.4 -> 1.0-1.9 (outdoor worlds 5, 7, 11: ~1.0), median
    rotation rms 0.93x, ATE 0.95x; better e.g. world 57 at 6 mm 0.0067 -> 0.0042 deg,
    world 9 0.0071 -> 0.0056, world 45's ATE at 2 cm 190 -> 93 mm; worse: world 15 at
    6 mm 0.0030 -> 0.0038 deg, ATE 0.59 -> 1.84 mm, world 5's ATE 2.6 -> 4.1 mm (rotation
    better), world 57's 0.84 -> 1.12 mm, world 13's rotation at 2 cm 0.0070 -> 0.0084:
    off (the faster choice, not worse in the median). "trend" (the default): the recent
    twists extrapolated one epoch along the straight line through them, its slope shrunk
    by how well their residuals determine it (:func:`planodom.odometry.trend.trend_twist`,
    the mean before 4 of them; the twist the trend rescue tries, ``odometry.
    map_trend_rescue``, is then the mean). An epoch's own twist changes smoothly (a turn,
    the sway), and the mean lags it by half the window. Offline over the own twists of a
    "mean" run (150 epochs), the median rotation-rate error of the mean / the last / the
    trend: world 7 (indoor) 0.61 / 0.22 / 0.07 deg/s at 6 mm, 0.64 / 0.29 / 0.24 at 2 cm;
    world 13 (indoor) 1.66 / 0.55 / 0.25 and 1.65 / 0.57 / 0.31; world 15 (outdoor) 1.26
    / 0.43 / 0.27 and 1.28 / 0.43 / 0.28 (over the tolerance in 75-100 % of the epochs
    with the mean, 0-17 % with the trend; the line through the last two, unshrunk:
    0.08-0.14 deg/s at 6 mm but 0.22-0.43 at 2 cm). Measured mean -> trend (150 epochs,
    6 mm and 2 cm; docs/RESULTS.md, LIDARSPEED): extractions an epoch on the indoor lidar
    worlds 1, 7, 13, 19, 65, 71 1.5-2.6 -> 1.0-1.5, planodom's CPU time 1.2-2.0x less;
    lidar worlds 1-19 and 61-79 odd: see docs/RESULTS.md for the per-world figures and
    the worlds that got worse. KITTI raw 0005 (no point times) byte-identical."""
    motion_bound_gate: bool = False
    """A registration whose step exceeds the motion bounds the run assumes
    (``association.max_translation_m``, ``max_rotation_deg``, the rig's motion_bounds)
    contradicts that assumption: lost track, not a measurement. On: it is reported
    unresolved and ``inconsistent`` and bridged by constant velocity (the map then rebuilt
    from the scan). Only the epoch's final estimate is judged, once the streaming odometry
    has chosen it (:meth:`~planodom.odometry.planemap.PlaneMapOdometry.judged`); judging
    every extraction tried, as before, bridged wrong first attempts that extracting the
    epoch again corrects (procedural lidar world 19 at 6 mm, 300 epochs: ATE 0.0087 ->
    0.19 m then, 0.0023 m now, one epoch bridged). Measured now on the ten procedural lidar
    worlds of ``experiment generalisation`` (300 epochs, 6 mm and 2 cm) and KITTI raw
    0005: bit-identical with it on, but for that one better world. Still off by default:
    a platform that truly turns faster than the bounds is bridged too (a hand-held VLP-16
    corridor walk's true 31 deg turn: ATE against KISS-ICP 0.165 -> 0.242 m, measured with
    the earlier gate; the turn is beyond the bounds either way), while on a room where both
    lose track it bridges 3-9 m "ok" steps. Off, ``planodom run`` / ``smooth`` warn of
    steps beyond the bounds."""
    hypothesis_bounds: Literal["score", "prefer_within"] = "prefer_within"
    """How the hypotheses of a suspicious registration are ranked (module
    :mod:`planodom.odometry.planemap.odometry`, step 3): "score", resolved first, then by
    the robust cost of all the scan's planes against the map; "prefer_within", resolved
    first, then those whose step is within the motion bounds (``association.
    max_translation_m``, ``max_rotation_deg``), then the cost. A symmetric room or
    corridor (a box seen from inside) fits as well turned by 180 deg as not; the motion
    bounds break that tie, and a hypothesis beyond them still wins when none within them
    is resolved (a platform that truly turns faster than its bounds keeps its step).
    Measured together with ``extraction.organised_gap: grazing`` on the lidar worlds 1-39
    (odd, 300 epochs, 6 mm and 2 cm) and KITTI 0005: unchanged (world 5 within 1e-6 of its
    figures) but for world 37 (a corridor entered in a 13-25 deg/s turn, with
    ``extraction.organised_gap: grazing``: its first steps 146, 70 and 96 deg off, then
    within 0.03 deg; see that field for the run's figures). Not measured: a platform
    turning beyond its bounds while a wrong hypothesis within them resolves (the
    hand-held VLP-16 corridor of docs/RESULTS.md is not on the machine any more); such a
    recording should state its bounds (``rig.yaml`` motion_bounds)."""
    fallback: bool = True
    """Score other hypotheses when the map result is suspicious (zero velocity, the
    scan-to-scan registration with widening gates, LDA without motion bounds)."""
    lda_planes: Annotated[int, Field(ge=3)] = 25
    """LDA in the fallback uses at most this many planes per scan (best-conditioned, at
    most ``lda_per_direction`` per direction): its candidates grow with the square."""
    lda_per_direction: Annotated[int, Field(ge=1)] = 3
    """...and at most this many of nearly one direction (ground patches say nothing about
    yaw; LDA needs the walls)."""
    min_plane_points: int | None = Field(10, ge=3)
    """Extraction limits while the map pipeline runs (None: the extraction section's):
    fewest points of a plane. The moment cost weights every plane by its own information
    (an exact point sum), so small planes (poles, kerbs, house fronts along a street) help
    rather than hurt. Measured on KITTI 0005 (10 / 0.1 m / 10 deg against the extraction's
    20 / 0.2 m / 1 deg: 0.081 deg 3.55 cm against 0.087 deg 4.12 cm): not tuned elsewhere."""
    min_plane_width_m: float | None = Field(0.1, ge=0)
    """Likewise the smallest plane width (m; see ``min_plane_points``)."""
    max_normal_sigma_deg: float | None = Field(10.0, gt=0, le=180)
    """Likewise the largest normal 1-sigma (deg) of a plane kept (see ``min_plane_points``)."""
    initial_rotation_deg: float = Field(5.0, gt=0, le=180)
    """Association gate (rotation) before any motion was measured: the first pair is
    also scored against the fallback hypotheses, so this only starts the search."""
    initial_translation_m: Positive = 1.0
    """Likewise for translation (m)."""

    def extraction_changes(self) -> dict[str, Any]:
        """The extraction fields this section overrides while the map pipeline runs, as
        dotted changes for :meth:`planodom.config.PlanodomConfig.updated`."""
        names = ("min_plane_points", "min_plane_width_m", "max_normal_sigma_deg")
        return {f"extraction.{k}": getattr(self, k) for k in names if getattr(self, k) is not None}
