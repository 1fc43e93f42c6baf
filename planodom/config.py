"""The one typed configuration of the planodom pipeline (pydantic, YAML in and out).

Every tunable threshold lives here with its unit in its name or docstring. Each stage owns
one section; ``PlanodomConfig`` nests them. Angles in configs are in degrees where the
field name says ``_deg``; everything else is SI.
"""

from __future__ import annotations

from pathlib import Path

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError

from planodom.errors import ConfigError


class Section(BaseModel):
    """Base of every config section: unknown keys are errors, values are validated."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True)


class ExtractionConfig(Section):
    """Plane extraction (planodom.extraction).

    Distance tolerances scale with the sensor noise: ``sigma`` is ``range_noise_m``, or
    the across-line noise estimated from the epoch's own scan lines when that is larger
    (``estimate_noise``); a tolerance is ``max(factor * sigma, tolerance_floor_m)``.
    """

    mode: str = "auto"
    """"auto", "rig2d" or "lidar". auto: the 2D-rig path when ``ring`` is present with at
    most ``max_rig_rings`` distinct values, else the 3D (lidar) path."""
    max_rig_rings: int = 8
    """Most scan lines (rings) an epoch of a 2D-scanner rig has (auto mode)."""
    range_noise_m: float = 0.006
    """Expected range noise sigma of the sensor (m); default: SICK LMS 221 (paper, VI-A)."""
    estimate_noise: bool = True
    """Also estimate sigma from second differences along the scan lines; use the larger."""
    tolerance_floor_m: float = 0.02
    """Smallest distance tolerance (m): trace curvature from motion within one sweep
    (about v / scan rate, 2 cm at 1.5 m/s and 75 Hz), deskew residue, float32 hits."""
    sweep_gap_factor: float = 2.5
    """A time step above this many median beam intervals starts a new sweep (2D rig)."""
    min_gap_m: float = 1.0
    """Consecutive points of a scan line farther apart than max(this, gap_range_ratio *
    range) start a new run (m)."""
    gap_range_ratio: float = 0.1
    """Range-proportional part of the gap threshold (m per m of range)."""
    split_sigma_factor: float = 4.0
    """A run is split where a point lies more than this many sigma from its chord."""
    min_segment_points: int = 3
    """Fewest points of a trace (the straight segments of one scanner on one line,
    merged over the epoch's sweeps) kept for grouping. Single segments of two points are
    kept until merged: one sweep may put only two beams on a distant or narrow wall."""
    min_segment_length_m: float = 0.1
    """Shortest straight segment kept for grouping (m)."""
    max_seed_direction_error_deg: float = 3.0
    """A segment seeds a plane only if its direction is known to this (deg), predicted
    as sigma * sqrt(12 / N) / length (line fit of N points spread over length)."""
    min_cross_angle_deg: float = 10.0
    """Two traces determine a plane only if they cross at least at this angle (deg); at
    10 deg the normal's error across the traces is about 1 / sin(10 deg) = 5.8 times the
    error along them. Traces of one ring never seed a plane (they are parallel, or lie in
    one scan plane)."""
    trace_parallel_deg: float = 2.0
    """Segments of one ring in nearby sweeps merge into one trace when their directions
    differ by less than this (deg) plus three times their predicted direction errors
    (a turn of 20 deg/s moves a direction by 0.3 deg between 75 Hz sweeps)."""
    trace_step_m: float = 0.1
    """...and when one's centroid lies within this (m) plus the member tolerance of the
    other's line: the displacement of a trace between sweeps (0.1 m at 75 Hz is 7.5 m/s)."""
    max_unskewed_span_s: float = 0.015
    """Without a twist (no deskewing) and with per-point times spread over more than this
    (s), the 2D-rig path only combines points acquired within this span: traces, seeds and
    planes are built per time window (about one sweep of a 75 Hz scanner, 1 / 75 s), i.e.
    from the crossing traces of a scanner pair in the same sweep, between which the
    vehicle moved at most ``max_unskewed_motion_m``. Each wall then gives one plane per
    window; the earliest (closest to the reference time) is kept, so a plane is off by
    about the motion from the reference time to its window. With a twist this is unused."""
    max_unskewed_motion_m: float = 0.03
    """Vehicle displacement assumed within one ``max_unskewed_span_s`` window when points
    are not deskewed (m): 2 m/s x 1 / 75 s = 2.7 cm. Added to the member tolerance, and
    half of it to the RMS limit of a plane, in that case only."""
    max_unskewed_speed_m_s: float = 5.0
    """Without a twist, two planes from different time windows are one wall seen twice
    when their normals are within ``unskewed_repeat_deg`` and their offsets within the
    member tolerance plus this speed (m/s) times their time difference."""
    min_unskewed_windows: int = 3
    """Without a twist, a wall is a plane only when it is found in at least this many time
    windows (of the ~7 sweeps of a 10 Hz epoch): two lines of one sweep far apart can be
    coplanar by chance, not in several sweeps. On the paper loop at 6 mm, 1 / 2 / 3 gave
    85 / 88 / 91 % precision for 5.9 / 5.8 / 5.75 good planes per epoch. The kept plane's
    normal and offset are extrapolated to the reference time from its windows (a
    straight line in time)."""
    unskewed_repeat_deg: float = 5.0
    """Normal angle (deg) within which planes of two time windows may be one wall (the
    turn of the vehicle over an epoch plus the fit error of one sweep's traces)."""
    plane_gap_m: float = 10.0
    """2D rig: a plane keeps only the traces connected to its seed through traces whose
    centre lines are at most max(this, gap_range_ratio * range) apart (m); coplanar walls
    separated by a wider gap are separate planes (and get their own extents), and two
    coplanar-by-chance traces far apart do not seed a plane. Not smaller: the two
    crossing traces of one wall often meet only where their lines are extended (on the
    paper loop at 6 mm, recall with 4 / 6 / 10 m / no limit: 81 / 90 / 91 / 91 %; without a
    twist 10 m raised precision from 96 % to 99 %)."""
    min_traces_high_noise: int = 2
    """When sigma exceeds ``tolerance_floor_m`` a plane needs this many traces (two
    crossing ones of two scanners plus one more): two traces of two walls that meet are
    then coplanar within the tolerance by chance. 2 (default) disables it: on the paper
    loop at 10 cm, 3 raised precision from 70 % to 78 % but cut recall from 63 % to 24 %."""
    member_sigma_factor: float = 3.0
    """A segment joins a plane when its centroid and its ends lie within this many sigma."""
    max_rms_sigma_factor: float = 1.5
    """A group of segments is a plane only if the RMS distance of its points to their
    fitted plane is at most max(this * sigma, rms_floor_m): two traces of two walls can be
    coplanar by coincidence (within the tolerance), but not flat to the noise level."""
    rms_floor_m: float = 0.001
    """Floor of the RMS test above (m): deskew and ray-casting residue of noise-free data."""
    inlier_sigma_factor: float = 3.5
    """Final point inliers: residual within this many robust sigmas (1.4826 MAD) of the
    fit, iterated; at most 0.05 % of Gaussian inliers are lost."""
    min_plane_points: int = 20
    """Fewest inlier points of a plane."""
    min_plane_width_m: float = 0.2
    """Smallest in-plane width of a plane's inliers (m), measured as 2 sqrt(lambda2 / N)
    along the minor in-plane axis; thinner sets are lines, not planes."""
    max_normal_sigma_deg: float = 1.0
    """Planes whose normal is known only to worse than this are dropped (deg; the 1-sigma
    error sqrt(trace Cov(n)) of the fit, :mod:`planodom.extraction.fitting`): narrow
    strips at high noise, whose offsets at a 10 m lever arm are off by ~0.2 m. Such a
    plane adds little to a rotation known to ~0.03 deg at 6 mm noise. Measured on the
    paper loop at 10 cm (every other epoch of a lap): it drops 36 % of the planes that
    miss their wall by 3 deg / 0.15 m and 1.8 % of the others (precision 89 -> 93 %);
    nothing at 6 mm and 2 cm."""
    viewpoint_height_m: float = 1.0
    """Without sensor origins normals point towards (0, 0, this) in the base frame (m)."""
    covariance_sigma_floor_m: float = 1e-4
    """Lower bound of the residual sigma used in the fit covariance (m), so that noise-free
    data gives a finite information matrix."""
    confidence_points_ref: float = 50.0
    """CPEF point-count scale: w_count = 1 - exp(-N / this)."""
    confidence_width_ref_m: float = 1.0
    """CPEF extent scale (m): w_extent = 1 - exp(-width / this)."""
    voxel_size_m: float = 0.3
    """3D path: voxel size (m) of the cloud RANSAC runs on (inliers are refit at full
    resolution, so this sets speed and the smallest plane, not precision)."""
    ransac_iterations: int = 300
    """3D path: most RANSAC iterations per plane (planodom.extraction.ransac)."""
    ransac_probability: float = 0.999
    """3D path: RANSAC stops early once it has this probability of an all-inlier sample."""
    max_planes: int = 40
    """3D path: most planes searched per epoch."""
    cluster_gap_deg: float = 3.0
    """3D path: coplanar inliers separated, as seen from the viewpoint, by a gap wider
    than this angle (deg) are separate planes. An angle, not a distance, because a
    lidar's rings spread apart with range (about 1 deg apart on a 32-beam unit)."""
    seed: int = 0
    """3D path: seed of the RANSAC's numpy generator (one per scan: the same scan gives
    the same planes in every run)."""
    range_image: bool = True
    """3D path with ``ring``: grow planes on the range image (ring x firing grid,
    planodom.extraction.rangeimage) instead of the RANSAC loop; RANSAC is still used
    without rings or when the pixel normals are too noisy (next field)."""
    region_max_normal_error_deg: float = 4.0
    """Range image: region growing only when the median predicted pixel-normal error
    (from sigma and the pixel spacing) is at most this (deg); else RANSAC. Walls meet the
    ground and each other at tens of degrees; a few degrees of noise keeps them apart."""
    region_window: int = 3
    """Range image: half-width (columns) of the row tangent of a pixel normal; its error
    falls as 1 / (window^1.5) while pixels within it of an edge get no normal."""
    region_normal_sigmas: float = 3.0
    """Range image: two neighbouring pixels join when their normals differ by at most
    region_normal_floor_deg plus this many predicted errors (and their points lie within
    the member tolerance plus this many errors times their distance of each other's
    tangent planes)."""
    region_normal_floor_deg: float = 2.0
    """Range image: angle allowance (deg) added to the predicted normal error of two
    pixels (round-off and ray-casting residue at sigma = 0)."""
    region_azimuth_columns: bool = False
    """Range image without usable times (all equal): take columns from the azimuth about
    the viewpoint instead of falling back to RANSAC. Off: with the sensor away from the
    base origin, azimuth bins collide and split walls (paper loop, lidar32, sigma = 0
    snapshot: recall 81 % against 100 % with RANSAC)."""
    region_merge_deg: float = 1.0
    """Range image: two grown pieces near in the grid are one plane when their TLS normals
    differ by at most this (deg) plus 3 sigma / sqrt(l2) of each (their predicted
    errors) and each centroid lies within the member tolerance of the other's plane."""


class AssociationConfig(Section):
    """Lenient and strict data association (planodom.association).

    The absolute constraints assume a maximum motion between two consecutive epochs:
    ``max_translation_m`` and ``max_rotation_deg`` (the defaults allow 10 m/s and 200 deg/s
    at 10 Hz epochs). With a motion prior (the constant-velocity prediction) the bounds
    are ``prior_translation_m`` / ``prior_rotation_deg`` around the prior instead. A
    dataset with faster motion or a lower epoch rate must raise them (config file or
    ``rig.yaml``); when epoch k is associated with epoch k - delta, the streaming
    odometry multiplies the per-epoch bounds by delta.
    """

    parallel_angle_deg: float = 15.0
    """Plane pairs whose normals are closer than this (or to its opposite) are parallel."""
    dihedral_tol_deg: float = 5.0
    """LDA: two pairs are candidates when their dihedral angles differ by at most this."""
    max_translation_m: float = 1.0
    """Assumed maximum translation between consecutive epochs, metres (no prior)."""
    max_rotation_deg: float = 20.0
    """Assumed maximum rotation angle between consecutive epochs, degrees (no prior)."""
    prior_translation_m: float = 0.3
    """Allowed deviation from the motion prior's translation, metres."""
    prior_rotation_deg: float = 5.0
    """Allowed deviation from the motion prior's rotation, degrees."""
    normal_tol_deg: float = 5.0
    """Margin for noise on a plane normal's direction, degrees (added to rotation bounds)."""
    offset_tol_m: float = 0.2
    """Margin for noise on plane offsets and pair reference points, metres."""
    overlap_margin_m: float = 1.0
    """Margin of the support-overlap test (bounding circles of the support polygons), m."""
    strict_normal_deg: float = 3.0
    """SDA: maximum angle between a previous normal and a rotated current normal, degrees."""
    strict_offset_m: float = 0.15
    """SDA: margin on offset differences beyond the translation bound, metres."""
    min_line_verticality: float = 0.2
    """Minimum |v_z| of a pair's unit intersection direction to define a reference point."""

    def model_post_init(self, context: object, /) -> None:
        for name, value in self:
            if value is not None and not value > 0:
                raise ConfigError(f"association.{name}: must be > 0, got {value!r}")
        if self.parallel_angle_deg >= 90.0 or self.min_line_verticality > 1.0:
            raise ConfigError("association: parallel_angle_deg < 90 and min_line_verticality <= 1")


class OdometryConfig(Section):
    """Rotation / translation consensus and the divide-and-conquer pipeline.

    Pipelines (paper Fig. 3): ``"wocsc"`` = (LDA, WOCSC rotation, WOCSC translation);
    ``"sda-mean"`` = (LDA, WOCSC rotation, SDA, mean translation "cog"); ablations
    ``"ocsc"`` = unweighted consensus for both, ``"mean"`` = chordal mean rotation of all
    LDA candidates, SDA and mean translation.
    """

    pipeline: str = "wocsc"
    """One of "wocsc", "sda-mean", "ocsc", "mean"."""
    delta: int = 1
    """Associate epoch k with epoch k - delta (paper's future work: delta > 1)."""
    rotation_inlier_deg: float = 3.0
    """A plane association agrees with a rotation when the normals match within this."""
    translation_inlier_m: float = 0.1
    """A pair agrees with a translation when its reference points match within this, m."""
    truncate_rotation_deg: float | None = None
    """Truncate per-element rotation errors at this angle (None: plain squared error)."""
    truncate_translation_m: float | None = None
    """Truncate per-element translation errors at this distance, m (None: plain)."""
    translation_min_angle_deg: float = 20.0
    """Pairs closer than this to parallel give no reference point (its error grows as
    1 / sin(angle)); rotation uses every non-parallel pair."""
    condition_weights: bool = True
    """Weight a pair's reference point by ``w1 w2 sin^2(angle)`` per epoch (its intersection's
    conditioning: offset noise moves it by ~ sigma_d / sin(angle)); False: ``w1 w2`` only."""
    best_partner: bool = True
    """An element with several LDA partners (ambiguous association) is scored once, with
    its best partner under each candidate; False scores every association (all count)."""
    estimate_z: bool = True
    """Estimate the vertical translation from associated ground-like planes."""
    z_plane_max_tilt_deg: float = 30.0
    """Up-facing planes tilted less than this from horizontal give the vertical translation."""
    use_motion_prior: bool = True
    """Streaming: use the constant-velocity prediction as prior for association."""
    retry_without_prior: bool = True
    """Repeat LDA with the prior-free bounds when the prior leaves no candidate."""
    deskew: bool = True
    """Streaming: deskew each epoch with the constant-velocity twist of the last estimate."""
    deskew_iterations: int = 2
    """Streaming: extract a time-spread epoch again with its own estimate's twist, at most
    this many times (see the two tolerances below); 0: the prediction only."""
    deskew_rate_tolerance_deg_s: float = 0.5
    """Re-extract when the epoch's own angular rate differs from the one it was deskewed
    with by more than this, deg/s (0.5 deg/s smears a point 20 m away by 1.7 cm at 10 Hz;
    one epoch's rotation is far more precise)."""
    deskew_speed_tolerance_mps: float = 0.5
    """Likewise for the linear velocity, m/s; larger than the noise of one epoch's
    velocity (a few cm per epoch at 6 mm), whose smear does not grow with range."""
    velocity_window: int = 5
    """Streaming: the predicted linear velocity is the median over this many recent
    measured steps (the angular rate is the last step's)."""
    epoch_period_s: float = 0.1
    """Epoch period used when epochs come without times, seconds."""
    min_sigma_rotation_deg: float = 0.001
    """Floor of the reported per-axis rotation sigma, degrees."""
    min_sigma_translation_m: float = 0.0005
    """Floor of the reported per-axis translation sigma, metres."""

    def model_post_init(self, context: object, /) -> None:
        if self.pipeline not in ("wocsc", "sda-mean", "ocsc", "mean"):
            raise ConfigError(
                f"odometry.pipeline: expected wocsc, sda-mean, ocsc or mean, got {self.pipeline!r}"
            )
        if self.delta < 1:
            raise ConfigError(f"odometry.delta: must be >= 1, got {self.delta}")
        if self.velocity_window < 1:
            raise ConfigError(f"odometry.velocity_window: must be >= 1, got {self.velocity_window}")
        if self.deskew_iterations < 0:
            raise ConfigError(
                f"odometry.deskew_iterations: must be >= 0, got {self.deskew_iterations}"
            )
        for name, value in self:
            if isinstance(value, float) and not value > 0:
                raise ConfigError(f"odometry.{name}: must be > 0, got {value!r}")


class SmoothingConfig(Section):
    """Factor-graph smoothing (planodom.smoothing).

    Noise models come from the data (odometry sigmas, plane fit covariances, confidences);
    the ``*_min_*`` fields are floors (noiseless simulations report zero covariances), the
    ``default_*`` fields stand in when an input carries no uncertainty at all.
    """

    delta_max: int = 3
    """D: relative poses (and associations) between epochs k - delta and k, delta = 1..D."""
    window: int = 10
    """W: epochs kept by the fixed-lag smoother (windowed mode); needs W > D."""
    windowed_backend: str = "incremental"
    """"incremental" (gtsam.IncrementalFixedLagSmoother, iSAM2) or "batch"
    (gtsam.BatchFixedLagSmoother, Levenberg-Marquardt over the window)."""
    plane_factor: str = "auto"
    """"global" (gtsam.OrientedPlane3Factor, world-frame landmark), "anchored"
    (LocalOrientedPlane3Factor, landmark in an anchor frame near its observations) or "auto":
    global for landmarks first seen within ``global_plane_max_distance_m`` of the world
    origin when no robust kernel is asked for planes, anchored otherwise."""
    global_plane_max_distance_m: float = 30.0
    """auto: farthest first-observing position (m) for a global plane factor."""
    min_landmark_epochs: int = 2
    """A tracked plane enters the graph once seen in at least this many epochs."""
    flipped_normals: str = "flip"
    """A measured normal more than 90 deg from the predicted one: "flip" it or "reject" it."""
    gate_normal_deg: float = 15.0
    """After orientation, a plane observation whose normal is farther than this from its
    landmark's prediction (at the initial estimate) is a wrong association: not added."""
    gate_offset_m: float = 2.0
    """Same for the offset along the normal, metres (allows odometry drift along a track)."""
    robust_kernel: str = "cauchy"
    """"none", "huber" or "cauchy", on the factors chosen by ``robust_between`` and
    ``robust_planes`` (outlier associations, wrongly extracted planes). Cauchy: its
    influence vanishes for gross outliers, while Huber's stays at threshold / sigma per
    factor, so one precise but wrong plane outweighs several less precise right ones (a
    ground plane 2.8 deg off with a 0.01 deg sigma turned a pose by 2 deg at 2 cm range
    noise, experiments/smoothing_consistency.py)."""
    robust_threshold: float | None = None
    """Kernel parameter in whitened units (sigmas); None: 1.345 (Huber), 2.3849 (Cauchy)."""
    robust_between: bool = True
    """Robust kernel on the 5-DoF between factors."""
    robust_planes: bool = True
    """Robust kernel on the plane factors (forces anchored plane factors in auto mode)."""
    default_rotation_sigma_rad: float = 0.005
    """Per-axis rotation sigma of a relative pose without sigmas, rad."""
    default_translation_sigma_m: float = 0.05
    """Per-axis horizontal translation sigma of a relative pose without sigmas, m."""
    min_rotation_sigma_rad: float = 1e-6
    """Floor of the between factors' rotation sigmas, rad (added in quadrature; the
    odometry floors its own sigmas, ``odometry.min_sigma_*``)."""
    min_translation_sigma_m: float = 1e-5
    """Floor of the between factors' translation sigmas, m."""
    default_plane_normal_sigma_rad: float = 0.01
    """Normal sigma (per tangent axis) of a plane without covariance, rad."""
    default_plane_offset_sigma_m: float = 0.02
    """Offset sigma of a plane without covariance, m."""
    min_plane_normal_sigma_rad: float = 1e-6
    """Floor added (in quadrature) to the plane factors' normal sigmas, rad: a guard for
    planes without uncertainty (synthetic data). It must stay far below the fit's
    uncertainty: added to the diagonal, it spoils the fit's strong normal-offset
    correlation, and the former 1e-4 rad and 1 mm made the plane covariances (median
    NEES 0.7 against chi2(3)'s 2.4) and the smoothed poses three times too cautious at
    6 mm range noise."""
    min_plane_offset_sigma_m: float = 1e-5
    """Floor added (in quadrature) to the plane factors' offset sigma, m."""
    plane_covariance_scale: float = 1.0
    """Multiplies every plane covariance (the extraction's TLS fit covariance)."""
    plane_confidence_scaling: bool = False
    """Also divide a plane's covariance by its CPEF confidence. Off: the TLS covariance
    already grows with the fit residual and shrinks with point count and extent, and on
    the simulated loop it matches the planes' errors (median NEES 2.3 against chi2(3)'s
    2.4 at 6 mm and 2 cm), while dividing by the confidence (median 0.4-0.5) made it two
    to three times too cautious (experiments/smoothing_consistency.py)."""
    between_factors: str = "untracked"
    """Which resolved relative poses become 5-DoF between factors. "all": every one.
    "untracked": only those whose source planes (the odometry's winning rotation and
    translation pairs, ``RelativeMeasurement.sources``) are not plane factors of a shared
    landmark in both epochs already: a relative pose is a function of its planes, so
    adding it beside their plane factors counts the same measurements twice (up to 2 D
    times with D deltas): "all" makes the smoothed poses' NEES 10-40 % larger (e.g. 4.9
    against 3.6 on the loop, 7.1 against 5.2 in the canyon at 2 cm) at the same or a
    worse ATE (experiments/smoothing_consistency.py). Relative poses without sources
    (independent sensors) are always factors. "none": no between factors (plane factors
    only; a diagnostic), except the fallback factors."""
    vertical_sigma_m: float = 0.05
    """Weak prior on the change of height between consecutive epochs, m (z is unobserved
    by the 5-DoF factors; see planodom.smoothing.graph)."""
    fallback_rotation_sigma_rad: float = 0.05
    """Constant-velocity between factor for an epoch whose horizontal translation no
    relative pose measured (unresolved or rotation-only), rad."""
    fallback_translation_sigma_m: float = 0.5
    """Translation sigma of that fallback factor, m."""
    prior_sigma: float = 1e-4
    """Sigma of the prior fixing the first pose (gauge), rad and m."""
    max_iterations: int = 100
    """Levenberg-Marquardt iterations (batch)."""
    relative_error_tol: float = 1e-4
    """Levenberg-Marquardt stops when the error decreases by less than this fraction (with
    robust kernels the last iterations creep: 1e-6 triples the time for < 0.1 % of ATE)."""
    relinearize_threshold: float = 0.01
    """iSAM2 relinearisation threshold (incremental windowed backend)."""
    compute_covariances: bool = True
    """Batch: marginal covariances of the poses (gtsam.Marginals)."""
    covariance_inlier_quantile: float | None = 0.99
    """Batch covariances: a robust factor whose squared whitened error at the estimate is
    within this quantile of chi2(its dimension) counts with full (Gaussian) weight, others
    with the robust kernel's weight (planodom.smoothing.batch.covariance_graph); the
    kernel's down-weighting of inliers would otherwise inflate the covariances by about
    1.5 (Cauchy). None: the robust weights throughout."""
    covariances_relative_to_first: bool = True
    """Batch: the poses' covariances are relative to the first pose (conditioned on it),
    as the poses are: the first pose's prior (``prior_sigma``) only fixes the gauge, and
    its uncertainty would otherwise be added to every pose's (``prior_sigma`` times the
    distance in translation). False: gtsam's marginals with that prior."""

    def model_post_init(self, context: object, /) -> None:
        choices = {
            "windowed_backend": ("incremental", "batch"),
            "plane_factor": ("auto", "global", "anchored"),
            "flipped_normals": ("flip", "reject"),
            "robust_kernel": ("none", "huber", "cauchy"),
            "between_factors": ("all", "untracked", "none"),
        }
        for name, allowed in choices.items():
            if getattr(self, name) not in allowed:
                raise ConfigError(
                    f"smoothing.{name}: expected one of {', '.join(allowed)}, "
                    f"got {getattr(self, name)!r}"
                )
        if self.delta_max < 1:
            raise ConfigError(f"smoothing.delta_max: must be >= 1, got {self.delta_max}")
        if self.window <= self.delta_max:
            raise ConfigError(
                f"smoothing.window: must exceed delta_max ({self.delta_max}), got {self.window}"
            )
        q = self.covariance_inlier_quantile
        if q is not None and not 0.0 < q <= 1.0:
            raise ConfigError(f"smoothing.covariance_inlier_quantile: must be in (0, 1], got {q}")
        if self.min_landmark_epochs < 2:
            raise ConfigError(
                f"smoothing.min_landmark_epochs: must be >= 2, got {self.min_landmark_epochs}"
            )
        for name, value in self:
            if isinstance(value, float) and not value > 0:
                raise ConfigError(f"smoothing.{name}: must be > 0, got {value!r}")


class PlanodomConfig(Section):
    """All sections of the pipeline."""

    extraction: ExtractionConfig = ExtractionConfig()
    association: AssociationConfig = AssociationConfig()
    odometry: OdometryConfig = OdometryConfig()
    smoothing: SmoothingConfig = SmoothingConfig()

    @classmethod
    def from_yaml(cls, path: str | Path) -> PlanodomConfig:
        """Load a (partial) config; missing keys keep their defaults."""
        path = Path(path)
        try:
            data = yaml.safe_load(path.read_text()) or {}
        except OSError as exc:
            raise ConfigError(f"{path}: cannot read config ({exc.strerror})") from exc
        except yaml.YAMLError as exc:
            raise ConfigError(f"{path}: not valid YAML ({exc})") from exc
        return cls.from_dict(data, source=str(path))

    @classmethod
    def from_dict(cls, data: dict, source: str = "config") -> PlanodomConfig:
        """Validate a nested dict; errors name the source and the field."""
        try:
            return cls.model_validate(data)
        except ValidationError as exc:
            first = exc.errors()[0]
            loc = ".".join(str(x) for x in first["loc"])
            raise ConfigError(f"{source}: field '{loc}': {first['msg']}") from exc
        except ConfigError as exc:  # raised by a section's own cross-field checks
            raise ConfigError(f"{source}: {exc}") from exc

    def to_yaml(self, path: str | Path | None = None) -> str:
        """The resolved config as YAML text; also written to ``path`` when given."""
        text = yaml.safe_dump(self.model_dump(mode="json"), sort_keys=False)
        if path is not None:
            Path(path).write_text(text)
        return text
