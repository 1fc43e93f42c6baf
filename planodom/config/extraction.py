"""Configuration of plane extraction (planodom.extraction)."""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, Field, model_validator

from planodom.config.extraction_span import SpanFields
from planodom.config.sweep import SweepConfig
from planodom.config.timewindows import TimeWindowConfig
from planodom.errors import ConfigError

__all__ = ["ExtractionConfig", "TimeWindowConfig"]


class ExtractionConfig(SpanFields):
    """Plane extraction (planodom.extraction).

    Distance tolerances scale with the sensor noise: ``sigma`` is ``range_noise_m``, or
    the across-line noise estimated from the epoch's own scan lines when that is larger
    (``estimate_noise``); a tolerance is ``max(factor * sigma, tolerance_floor_m)``.

    Every numeric field is range-checked and finite; :meth:`_cross_checks` relates fields
    that only make sense together. Both raise at load (a YAML file fails with a one-line
    :class:`planodom.errors.ConfigError` naming the field).
    """

    model_config = ConfigDict(allow_inf_nan=False)

    mode: Literal["auto", "rig2d", "lidar"] = "auto"
    """Which path runs. auto: the 2D-rig path when ``ring`` is present with at most
    ``max_rig_rings`` distinct values, else the 3D (lidar) path."""
    max_rig_rings: int = Field(8, ge=1)
    """Most scan lines (rings) an epoch of a 2D-scanner rig has (auto mode)."""
    range_noise_m: float = Field(0.006, ge=0)
    """Expected range noise sigma of the sensor (m); default: SICK LMS 221 (paper, VI-A)."""
    estimate_noise: bool = True
    """Also estimate sigma from second differences along the scan lines; use the larger."""
    deskew_jacobian: bool = False
    """Give each plane of a scan with point times its first-order change with the
    deskewing twist (``Plane.deskew_jacobian``). Only ``smoothing.deskew_noise:
    twist_change_jacobian[_net]``, ``smoothing.covariance_model: sandwich`` (or "auto", the
    default, in the batch) and ``planemap.deskew_variance: twist_change`` use it, and they
    switch it on (PlanodomConfig; for "auto", the batch smoothing's ``smoothing_config``);
    off otherwise because it costs about 80 us per plane of 2 000 points."""
    time_moments: bool = False
    """Give each plane of a scan with point times its time moments (``PlaneSupport.
    time_moments``); ``planemap.twist_estimation`` reads them and switches this on."""
    tolerance_floor_m: float = Field(0.02, ge=0)
    """Smallest distance tolerance (m): trace curvature from motion within one sweep
    (about v / scan rate, 2 cm at 1.5 m/s and 75 Hz), deskew residue, float32 hits."""
    sweep_gap_factor: float = Field(2.5, gt=1)
    """A time step above this many median beam intervals starts a new sweep (2D rig)."""
    min_gap_m: float = Field(1.0, gt=0)
    """Consecutive points of a scan line farther apart than max(this, gap_range_ratio *
    range) start a new run (m)."""
    gap_range_ratio: float = Field(0.1, ge=0)
    """Range-proportional part of the gap threshold (m per m of range)."""
    split_sigma_factor: float = Field(4.0, gt=0)
    """A run is split where a point lies more than this many sigma from its chord."""
    min_segment_points: int = Field(3, ge=2)
    """Fewest points of a trace (the straight segments of one scanner on one line,
    merged over the epoch's sweeps) kept for grouping. Single segments of two points are
    kept until merged: one sweep may put only two beams on a distant or narrow wall."""
    min_segment_length_m: float = Field(0.1, ge=0)
    """Shortest straight segment kept for grouping (m)."""
    max_seed_direction_error_deg: float = Field(3.0, gt=0, le=90)
    """A segment seeds a plane only if its direction is known to this (deg), predicted
    as sigma * sqrt(12 / N) / length (line fit of N points spread over length)."""
    min_cross_angle_deg: float = Field(10.0, gt=0, le=90)
    """Two traces determine a plane only if they cross at least at this angle (deg); at 10 deg the
    normal's error across the traces is about 1 / sin(10 deg) = 5.8 times the error along them.
    Traces of one ring never seed a plane (they are parallel, or lie in one scan plane)."""
    max_seed_normal_error_deg: float = Field(0.0, ge=0, le=90)
    """Two traces crossing below ``min_cross_angle_deg`` (down to 2 deg) still seed a
    plane when its normal is predicted to this (deg), ``(err_i + err_j) / sin(angle)``
    from their direction errors: long traces of two scanners on a side wall cross at a
    few degrees. Default 0 (never), measured: 0.5 finds such walls on random worlds
    (world 0 at 6 mm: 8 -> 4 unresolved epochs) but the paper loop's ATE grows from
    0.085 to 0.16 m (0.2: 0.19 m); the narrow seeds' normals carry biases their
    predicted error does not hold."""
    trace_parallel_deg: float = Field(2.0, ge=0, le=90)
    """Segments of one ring in nearby sweeps merge into one trace when their directions
    differ by less than this (deg) plus three times their predicted direction errors
    (a turn of 20 deg/s moves a direction by 0.3 deg between 75 Hz sweeps)."""
    trace_step_m: float = Field(0.1, ge=0)
    """...and when one's centroid lies within this (m) plus the member tolerance of the
    other's line: the displacement of a trace between sweeps (0.1 m at 75 Hz is 7.5 m/s)."""
    single_scanner_min_sweeps: int = Field(0, ge=0)
    """2D rig, deskewed points: a wall seen by one scanner only is a plane when that
    scanner's lines of at least this many sweeps lie in it (parallel lines displaced by
    the motion between the sweeps, :mod:`planodom.extraction.rig2d.sweeplines`); 0: never
    (a plane needs two crossing scanners). At least 3 when on: two parallel lines are
    always coplanar. Off by default, measured: in world 6's gap at 6 mm (the even 2D-rig
    worlds of ``planodom experiment generalisation``, epochs 51-54) almost every wall the
    oracle fits is seen by one scanner only (a far wall in a turn); with the points
    deskewed along the true motion this finds 9-10 planes per epoch, all true walls,
    where the two-scanner rule finds 1-5. But such a plane's tilt about its lines is set
    by the deskewing, not by the wall: a turn rate off by 1 deg/s tilts it by 4-8 deg
    (walls at 30-70 m), the constant twist of the true motion by up to 0.8 deg. In the
    streaming odometry world 6 at 6 mm (150 epochs) went from 6 to 8 unresolved epochs,
    rotation rms 0.37 -> 3.1 deg, ATE 0.75 -> 13 m; on the ten even 2D-rig worlds (300
    epochs) unresolved 19 -> 37 at 6 mm and 76 -> 67 at 2 cm, median rotation rms 0.116
    -> 0.504 and 0.211 -> 0.332 deg, median ATE 0.19 -> 0.92 and 1.01 -> 1.61 m (world 8
    at 6 mm 0.28 -> 10 m). A use needs the motion within an epoch known to a few
    hundredths of a deg/s."""
    single_scanner_rate_sigma_deg_s: float = Field(0.0, ge=0)
    """A one-ring plane of a deskewed epoch: its covariance widened by a twist error of
    this (deg/s) and ``single_scanner_speed_sigma_mps``, kept out of the rotation
    (:mod:`planodom.extraction.rig2d.onescanner`). 0 and 0: the fit's alone (default:
    0.5 and 0.5 measured worse on worlds 166 and 178, docs/RESULTS.md, ONESCANNER)."""
    single_scanner_speed_sigma_mps: float = Field(0.0, ge=0)
    """Likewise for the linear velocity (m/s)."""
    twist_rate_sigma_deg_s: float = Field(0.0, ge=0)
    """2D-rig path with a twist: how far (deg/s) the angular rate the points were
    deskewed with may be off. A twist off by ``e`` moves a point acquired ``t`` after the
    reference time by about ``e t`` (times its range for the rate), so the points of one
    wall smear by ``e`` times half the epoch's time span about their plane; the member
    tolerance and the seed floor grow by that smear at the median point range, the RMS
    limit by half of it (as in time windows, :func:`.rig2d.windows.widened`). 0: the
    twist is taken as exact (default). Measured with 0.5 deg/s and 0.5 m/s (the deskewing
    policy's ``odometry.deskew_rate_tolerance_deg_s`` / ``deskew_speed_tolerance_mps``,
    the error it leaves) on the even 2D-rig worlds 0-18, 100 epochs: unresolved epochs
    36 -> 15 at 2 cm and 31 -> 11 at 6 mm, xy error lower on all worlds at 2 cm, rotation
    lower on 7 of 10 (world 2 at 2 cm: 0.79 -> 1.77 deg, world 6 at 6 mm: 0.23 -> 0.47
    deg); but the paper loop's quick start (10 Hz, its twist measured well) got worse,
    ATE 0.071 -> 0.175 m (0.2 deg/s, 0.1 m/s: 0.097 m), so it is off by default. The
    streaming odometry passes its own per-epoch values instead where the extraction with
    these loses an epoch (``odometry.twist_sigma``)."""
    twist_speed_sigma_mps: float = Field(0.0, ge=0)
    """Likewise for the linear velocity (m/s; a 0.2 m/s error deskews the walls of a 5 Hz
    epoch into 0-1 planes at the 2 cm tolerance floor). Default 0 (see above)."""
    time_windows: TimeWindowConfig = TimeWindowConfig()
    """The 2D-rig path without a twist: time windows (:class:`TimeWindowConfig`)."""
    sweep: SweepConfig = SweepConfig()
    """A spinning lidar's declared sweep convention: per-point times from the azimuth for
    clouds without them (:class:`SweepConfig`; off by default)."""
    plane_gap_m: float = Field(10.0, gt=0)
    """2D rig: a plane keeps only the traces connected to its seed through traces whose
    centre lines are at most max(this, gap_range_ratio * range) apart (m); coplanar walls
    separated by a wider gap are separate planes (and get their own extents), and two
    coplanar-by-chance traces far apart do not seed a plane. Not smaller: the two
    crossing traces of one wall often meet only where their lines are extended (on the
    paper loop at 6 mm, recall with 4 / 6 / 10 m / no limit: 81 / 90 / 91 / 91 %; without a
    twist 10 m raised precision from 96 % to 99 %)."""
    seed_spans_gap: bool = False
    """2D rig: a plane keeps the traces connected (``plane_gap_m``) to either trace of its
    seed pair, not only to the first, when the two are coplanar within their own noise
    (``3 sigma sqrt(1 / N_i + 1 / N_j)`` plus the slack of their direction errors,
    without ``tolerance_floor_m``): two long crossing traces stay one plane when they lie
    farther apart than the gap (an indoor floor seen by a scanner ahead and one behind,
    14 m apart, was dropped: the seed lost its second trace). Off by default, measured on
    the ten even 2D-rig worlds (300 epochs): the floor of indoor world 2 at 6 mm is
    extracted in 267 instead of 105 of 300 epochs (the planes it adds, with the true twist:
    all true surfaces, 0.018 deg median normal error); unresolved epochs 19 -> 23 at 6 mm
    and 76 -> 58 at 2 cm, the longest gap where the oracle measures 4 -> 4 and 3 -> 5
    (world 6 at 2 cm), median rotation rms 0.116 -> 0.104 and 0.211 -> 0.204 deg, xy
    2.06 -> 2.29 and 7.9 -> 6.4 cm, ATE 0.19 -> 0.32 and 1.01 -> 0.94 m. World 2 at 6 mm:
    rotation 0.53 -> 0.35 deg, xy 5.6 -> 4.6 cm but ATE 0.82 -> 3.3 m, its x error summed
    over the epochs the odometry calls degenerate (rotation only, the corridor's length
    bridged) 2 cm -> 1.5 m. Without the count test short traces of two walls 20 m apart
    (11-21 points) were taken for one plane; at 2 cm two long wall traces at one height
    still are (a horizontal plane: 5 of 100 epochs of world 12). Measured again on the
    even worlds 0-58 (300 epochs, off -> on): world 42's corridor gap (only its two walls
    kept; the floor's traces of two scanners crossing at 80 deg, 15 m apart) 15 -> 2
    unresolved epochs at 6 mm (longest gap 10 -> 1) and 35 -> 6 at 2 cm (16 -> 4); all
    worlds unresolved 75 -> 65 and 201 -> 149, median rotation 0.072 -> 0.074 and 0.199 ->
    0.193 deg, ATE 0.148 -> 0.196 and 0.78 -> 0.63 m (worse at 6 mm: world 2 0.82 -> 3.27,
    16 0.07 -> 0.48, 56 0.14 -> 0.86 m; with ``odometry.pairwise_reference_time: middle``
    rotation 0.047 / 0.165 deg, ATE 0.207 / 0.58 m): still off."""
    exclusive_seeds: bool = False
    """2D rig: a seed pair crossing beyond both its traces waits while one sharing a trace,
    on another plane, is closer to coplanar (:mod:`planodom.extraction.rig2d.seedconflicts`).
    Off: world 114 at 2 cm 1.13 -> 0.23 deg, but 2 at 2 cm 0.53 -> 1.23 (docs/RESULTS.md)."""
    own_scan_plane: Literal["kept", "dropped", "trimmed"] = "kept"
    """2D rig with a sensor origin per ring: what becomes of a group whose plane holds the
    sensor of one of its rings with two or more segments in it (that ring's rays within
    ``trace_parallel_deg`` of the plane), a tilted scanner's own scan plane taken for a
    wall (:mod:`planodom.extraction.rig2d.path`). ``trimmed``: that ring's segments leave
    the group, which stays a plane only if the rest still is one by the grouping's rules
    (two rings crossing at ``min_cross_angle_deg``, ``min_plane_points``, the RMS limit)
    and is refit on it (:func:`.rig2d.path.without_own_scan_plane`); ``dropped``: the
    whole group goes (:func:`.rig2d.path.spans_own_scan_plane`), grazing real floors and
    walls with it; ``kept``: no test. Off (``kept``) by default, measured (streaming
    odometry, ATE): ``trimmed`` takes world 32 at 2 cm from 3.23 to 0.84 m over 200
    epochs (whole lap 4.41 -> 1.05 m) and world 2 from 3.08 to 1.27 m, and leaves 13 more
    2D-rig worlds (200 epochs) and 25 (22-30, 40-78 even, 150 epochs) within 1 cm
    (world 50 -5.3 cm); but world 32 at 6 mm gets worse, 2.23 -> 2.89 m over 200 epochs
    (whole lap 2.95 -> 3.67 m), and with batch smoothing and loops 0.14 -> 3.55 m (loop
    end 6 mm -> 7.1 m): one step 0.10 m off (``refit_keeps_cross``), carried by the bridge
    through a corridor. ``dropped`` gives the same poses but on worlds 64, 76 (< 0.1 mm)."""
    sweep_tilt: Literal["kept", "trimmed"] = "kept"
    """2D rig, deskewed points (a twist, not in time windows): ``trimmed`` takes out of a
    group the rings whose lines of several sweeps are displaced farther across its plane
    than within it, beyond ``member_sigma_factor`` noise sigmas; the group stays a plane
    only if the rest still is one (as ``own_scan_plane: trimmed``). Two scanners' lines on
    two walls meeting at their edge are coplanar, a level "plane" between the walls; each
    scanner's lines climb its own wall as it moves (:mod:`.rig2d.sweeptilt`); the climb
    over the ring's time span must exceed the member tolerance. Off (``kept``), measured
    on the even worlds 0-38 (150 epochs): 354 -> 351 phantom planes, and its other
    changes are chance (world 26 at 6 mm ATE 9.9 -> 4.7 m, world 6 at 2 cm 1.0 -> 5.7 m);
    without the tolerance it took true walls (unresolved epochs 32 -> 73 at 6 mm)."""
    refit_keeps_cross: bool = False
    """2D rig: drop a group of two or more rings whose robust refit keeps one ring's line
    alone (:func:`.rig2d.path.lost_cross`, which gives the measurements). Off."""
    viewpoint_planes: Literal["kept", "rejected", "ransac"] = "ransac"
    """``rejected``: a fit whose inliers are as flat about a plane through their viewpoint
    as a plane must be about its own (RMS within ``member_sigma_factor`` noise sigmas) is
    not a plane (:func:`planodom.extraction.planes.builder.through_viewpoint`): a scan
    line lies on its laser's cone, so near-level lines across facades at several depths
    fit a thin level "plane" fixed to the sensor, which holds the odometry's roll and
    pitch still. Measured (300 epochs, lidar worlds 1-39 odd, rotation rms per epoch,
    default from the same code): 2 cm median 0.0083 -> 0.0061 deg, ATE 3.1 -> 2.0 mm
    (world 29 0.190 -> 0.121, 27 0.032 -> 0.0063, 13 0.021 -> 0.0065, 39 0.0087 ->
    0.0035); worse 37 (lost either way, 0.25 -> 0.64 deg, unresolved 53 -> 124), 23
    (0.032 -> 0.038), 15 (0.0054 -> 0.0057), ATE of 29 (18 -> 31 mm) and 9 (18 -> 29
    mm); 6 mm median 0.0037 -> 0.0036 deg, none worse in rotation (37: unresolved 110 ->
    138). But KITTI raw 0005 RPE rotation 0.0868 -> 0.0933 deg (translation 3.59 -> 3.61
    cm). ``ransac`` (default): the rule on the RANSAC loop's candidates only (the lidar
    path's fallback where pixel normals are too noisy, which is where the lines were
    taken for planes); an unorganised cloud's image (KITTI's path) and ringed range images
    keep every fit: KITTI 0005's poses are byte-identical. Lidar worlds 1-39 (odd, 300
    epochs, against the defaults of ``organised_gap: grazing``): at 6 mm only world 1
    changes (0.00452 -> 0.00433 deg); at 2 cm the median rotation 0.0083 -> 0.0066 deg
    (worst 312 -> 199x the oracle), ATE 3.11 -> 2.83 mm: world 13 0.021 -> 0.0065 deg
    (ATE 8.6 -> 1.0 mm), 27 0.032 -> 0.0062 (36 -> 1.7 mm), 29 0.190 -> 0.121, 39 0.0087
    -> 0.0034; worse: 23 0.0315 -> 0.0379 deg, 19 0.0083 -> 0.0087, 1 0.0117 -> 0.0121,
    ATE of 29 18 -> 31 mm, 35 1.6 -> 2.0 mm, 19 1.5 -> 1.6 mm, 7 3.6 -> 3.8 mm."""
    member_sigma_factor: float = Field(3.0, gt=0)
    """A segment joins a plane when its centroid and its ends lie within this many sigma."""
    max_rms_sigma_factor: float = Field(1.5, gt=0)
    """A group of segments is a plane only if the RMS distance of its points to their
    fitted plane is at most max(this * sigma, rms_floor_m): two traces of two walls can be
    coplanar by coincidence (within the tolerance), but not flat to the noise level."""
    rms_floor_m: float = Field(0.001, ge=0)
    """Floor of the RMS test above (m): deskew and ray-casting residue of noise-free data."""
    inlier_sigma_factor: float = Field(3.5, gt=0)
    """Final point inliers: residual within this many robust sigmas (1.4826 MAD) of the
    fit, iterated; at most 0.05 % of Gaussian inliers are lost."""
    min_plane_points: int = Field(20, ge=3)
    """Fewest inlier points of a plane."""
    min_plane_width_m: float = Field(0.2, ge=0)
    """Smallest in-plane width of a plane's inliers (m), measured as 2 sqrt(lambda2 / N)
    along the minor in-plane axis; thinner sets are lines, not planes."""
    max_normal_sigma_deg: float = Field(1.0, gt=0, le=180)
    """Planes whose normal is known only to worse than this are dropped (deg; the 1-sigma
    error sqrt(trace Cov(n)) of the fit, :mod:`planodom.extraction.planes.fit`): narrow
    strips at high noise, whose offsets at a 10 m lever arm are off by ~0.2 m. Such a
    plane adds little to a rotation known to ~0.03 deg at 6 mm noise. Measured on the
    paper loop at 10 cm (every other epoch of a lap): it drops 36 % of the planes that
    miss their wall by 3 deg / 0.15 m and 1.8 % of the others (precision 89 -> 93 %);
    nothing at 6 mm and 2 cm."""
    viewpoint_height_m: float = Field(1.0, gt=0)
    """Without sensor origins normals point towards (0, 0, this) in the base frame (m)."""
    covariance_sigma_floor_m: float = Field(1e-4, gt=0)
    """Lower bound of the residual sigma used in the fit covariance (m), so that noise-free
    data gives a finite information matrix."""
    confidence_points_ref: float = Field(50.0, gt=0)
    """CPEF point-count scale: w_count = 1 - exp(-N / this)."""
    confidence_width_ref_m: float = Field(1.0, gt=0)
    """CPEF extent scale (m): w_extent = 1 - exp(-width / this)."""
    voxel_size_m: float = Field(0.3, gt=0)
    """3D path: voxel size (m) of the cloud RANSAC runs on (inliers are refit at full
    resolution, so this sets speed and the smallest plane, not precision)."""
    ransac_iterations: int = Field(300, ge=1)
    """3D path: most RANSAC iterations per plane (planodom.extraction.lidar.ransac)."""
    ransac_probability: float = Field(0.999, gt=0, le=1)
    """3D path: RANSAC stops early once it has this probability of an all-inlier sample."""
    max_planes: int = Field(40, ge=1)
    """3D path: most planes searched per epoch."""
    cluster_gap_deg: float = Field(3.0, gt=0, le=90)
    """3D path: coplanar inliers separated, as seen from the viewpoint, by a gap wider
    than this angle (deg) are separate planes. An angle, not a distance, because a
    lidar's rings spread apart with range (about 1 deg apart on a 32-beam unit)."""
    seed: int = Field(0, ge=0)
    """3D path: seed of the RANSAC's numpy generator (one per scan: the same scan gives
    the same planes in every run)."""
    range_image: bool = True
    """3D path with ``ring``: grow planes on the range image (ring x firing grid,
    planodom.extraction.lidar.rangeimage) instead of the RANSAC loop; RANSAC is still used
    without rings or when the pixel normals are too noisy (next field)."""
    unorganised: Literal["rows", "ransac"] = "rows"
    """3D path without ``ring`` (an unorganised cloud: most recorded PCD / PLY / KITTI
    files). rows: recover the scan lines of the spinning lidar (ring-major file order or
    elevation modes, :mod:`planodom.extraction.lidar.rows`) and grow planes on a range
    image of square angular pixels (:mod:`planodom.extraction.lidar.organised`), RANSAC
    when no rows are found; ransac: the RANSAC loop always."""
    untimed_rings: Literal["rows", "ransac"] = "rows"
    """3D path, ``ring`` without usable times: rows: the rings, ordered by elevation, grow
    planes as an unorganised cloud's rows do (RANSAC when they are no scan lines); ransac:
    the RANSAC loop, as before (measured: planodom.extraction.lidar.path)."""
    region_max_normal_error_deg: float = Field(4.0, gt=0, le=90)
    """Range image: region growing only when the median predicted pixel-normal error
    (from sigma and the pixel spacing) is at most this (deg); else RANSAC. Walls meet the
    ground and each other at tens of degrees; a few degrees of noise keeps them apart."""
    ransac_normal_agreement_deg: float | None = Field(45.0, gt=0, lt=90)
    """3D path, a ringed scan (or recovered rows with times) whose range image is too
    noisy to grow regions on: a RANSAC plane is refused when more than half of its
    inliers that have a pixel normal differ from it by more than this (deg): a cut through
    the scan lines of several facades, not a surface
    (:mod:`planodom.extraction.lidar.agreement`). None: off. 45 deg: far beyond a pixel
    normal's predicted error where the rule applies (a few degrees), far below the 70-90
    deg between a cut and the facades it crosses; not fitted. Measured (lidar worlds 1-57
    odd but those without rings or times, 300 epochs, off -> 45): at 2 cm the 64-beam
    worlds 29 / 47 / 41 0.121 / 0.175 / 0.062 -> 0.0051 / 0.0185 / 0.0049 deg per epoch,
    ATE 31 / 34 / 131 -> 5.1 / 2.3 / 2.3 mm (their scans held ~25 such cuts in 45
    planes); worse: world 23 0.0379 -> 0.0400 deg (ATE 4.7 -> 3.1 mm), world 45's ATE 283
    -> 305 mm, world 1's 1.40 -> 1.61 mm (rotation 0.0121 -> 0.0104), world 13's 0.97 ->
    1.08, world 35's 2.00 -> 2.14; 15 of 25 worlds unchanged at 2 cm, 22 at 6 mm (the
    others within 6 %, world 57 better). KITTI 0005 (no ring: the organised image) is
    untouched, its poses byte-identical."""
    region_noisy_pixels: Literal["ransac", "masked"] = "ransac"
    """Range image whose median pixel-normal error stays over
    ``region_max_normal_error_deg`` at every row step: "ransac" hands the scan to the
    RANSAC loop; "masked" grows regions on the pixels whose own predicted error is within
    it (far surfaces, where the rows are far apart), at the tallest row step tried, the
    others joining planes only through the member tolerance. Measured (lidar worlds, 300
    epochs, 2 cm, rotation deg per epoch, ransac -> masked): worlds 29 / 47 / 41 (64
    beams) 0.121 / 0.175 / 0.062 -> 0.0021 / 0.0118 / 0.0013, ATE 31 / 34 / 131 -> 3.0 /
    1.6 / 2.3 mm, but world 1's ATE 1.4 -> 4.7 mm and world 13's 1.0 -> 2.9 mm, and on a
    synthetic 64-beam scan at 3 cm with walls 25-35 m away every wall pixel is over the
    limit and only the ground is found (RANSAC finds all seven planes): a scene whose
    surfaces are all near and noisy loses them. Off: the RANSAC loop with
    ``ransac_normal_agreement_deg`` keeps its recall."""
    region_window: int = Field(3, ge=1)
    """Range image: half-width (columns) of the row tangent of a pixel normal; its error
    falls as 1 / (window^1.5) while pixels within it of an edge get no normal."""
    region_normal_sigmas: float = Field(3.0, ge=0)
    """Range image: two neighbouring pixels join when their normals differ by at most
    region_normal_floor_deg plus this many predicted errors (and their points lie within the member
    tolerance plus this many errors times their distance of each other's tangent planes)."""
    region_normal_floor_deg: float = Field(2.0, ge=0, le=90)
    """Range image: angle allowance (deg) added to the predicted normal error of two
    pixels (round-off and ray-casting residue at sigma = 0)."""
    region_merge_deg: float = Field(1.0, ge=0, le=90)
    """Range image: two grown pieces near in the grid are one plane when their TLS normals
    differ by at most this (deg) plus 3 sigma / sqrt(l2) of each (their predicted
    errors) and each centroid lies within the member tolerance of the other's plane."""
    region_gap: Literal["incidence", "range"] = "incidence"
    """Range image: the gap rule between neighbouring pixels. range: ``max(min_gap_m,
    gap_range_ratio * range)`` in every direction; incidence: the ratio scaled by the
    angle between the two rays over the native column step (the incidence limit the rule
    gives a scan line's consecutive points; a sparse lidar's rows 2 deg apart no longer
    cut its floor, planodom.extraction.lidar.rangeimage; a grown piece over the RMS limit
    is then trimmed to its plane once instead of dropped). For the image of a ringed
    scan (or recovered rows with recorded times). Applied only where rows lie farther
    apart than columns. Measured on the procedural lidar worlds (10 worlds, 150 epochs,
    range -> incidence): the indoor 16-beam world 19 at 6 mm keeps floor and ceiling
    (true surfaces found 67 -> 96 %), rotation rms 0.0122 -> 0.0045 deg, ATE 9.4 -> 0.5 mm;
    median rotation 6.2 -> 5.8x the oracle at 6 mm, unchanged at 2 cm; the 32-beam
    worlds 9 and 15 lose up to a fifth of their rotation (at most 0.0007 deg). KITTI
    0005 (no ring: the organised image) and nebula's parked recordings: unchanged."""
    organised_gap: Literal["range", "incidence", "grazing"] = "grazing"
    """The same for the square-pixel image of an unorganised cloud
    (planodom.extraction.lidar.organised). range: unscaled. incidence: scaled by the
    native column step; it finds a 16-beam room's floor and ceiling, but measured on
    KITTI 0005 (HDL-64E, pixels ~2.3 native columns wide) it made RPE rotation 0.0967 deg
    and translation 3.63 cm against 0.0868 and 3.59 with range. grazing (default): the
    ratio scaled only as far as needed to keep whole a plane seen at
    ``organised_min_incidence_deg`` or more (the step the ratio refers to is
    ``gap_range_ratio * sin(organised_min_incidence_deg)``, not the native column), so
    pixels finer than that step (KITTI's 0.4 deg against 1 deg at 10 deg) keep the
    unscaled rule. Measured with ``planemap.hypothesis_bounds: prefer_within`` on the
    lidar worlds 1-39 (odd, 300 epochs, 6 mm and 2 cm; worlds from 21 on held out): only
    world 37 changes (indoor, 16 beams, no ring or time fields: floor and ceiling were
    lost, 37 of 150 epochs unresolved), ATE 4.0 -> 0.060 m at 6 mm and 1.83 -> 0.136 m at
    2 cm (KISS-ICP 0.26 / 0.25 m), unresolved 110 -> 9 and 53 -> 18; world 5 (64 beams,
    no ring or time) moves by under 1e-6 of its figures; KITTI 0005's poses are
    byte-identical."""
    organised_min_incidence_deg: float = Field(10.0, gt=0, lt=90)
    """``organised_gap: grazing``: the smallest incidence (deg, between the ray and the
    plane) at which the gap rule still keeps a plane whole. 10 deg: a floor 1 m below the
    sensor stays one plane out to 5.7 m (a room's or corridor's floor, ceiling and walls
    within a few metres); not fitted to a world."""
    organised_window_deg: float | None = Field(1.5, gt=0, le=90)
    """The square-pixel image of an unorganised cloud: the row tangent's half-width is
    ``region_window`` pixels, but at most this angle (deg; at least one pixel; None: no
    cap). A window counted in pixels spans an angle that grows with the pixel, and the
    pixel is the lidar's row spacing: 0.42 deg for a 64-beam unit, where 3 pixels span
    1.3 deg, but 2 deg for a 16-beam one, where 3 pixels span 6 deg and every plane under
    about 14 deg of azimuth is left without pixel normals (an outdoor 16-beam world at 6
    mm, walls 10-20 m wide at 25-40 m: 5 candidates of the ~20 surfaces the oracle fits;
    capped, one pixel: 13). 1.5 deg keeps the window that was measured on KITTI 0005
    (three 0.42 deg pixels; its poses byte-identical) and caps the sparse lidars' at one
    pixel. Measured on the procedural lidar worlds without ring or time fields (300
    epochs; rotation deg per epoch, ATE, unresolved, uncapped -> capped): world 43
    (outdoor, 16 beams, never used while the defaults were chosen) 0.060 -> 0.0043,
    0.19 m -> 7.6 mm, 26 -> 0 at 6 mm and 0.120 -> 0.0060, 2.04 m -> 8.8 mm, 56 -> 0 at
    2 cm (KISS-ICP 0.57 / 0.44 m); world 55 (the same kind) 0.98 m -> 4.5 mm and 1.50 m ->
    4.5 mm; world 37 (indoor, 16 beams) 0.074 -> 0.016, 60 -> 2.9 mm, 9 -> 0 and 0.087
    -> 0.022, 136 -> 3.9 mm, 18 -> 0; world 5 (64 beams on 512 columns: 0.7 deg pixels,
    two instead of three) ATE 3.07 -> 2.89 and 3.24 -> 2.81 mm, but xy per epoch 0.066
    -> 0.070 and 0.076 -> 0.085 cm; world 59 (64 beams, 1024 columns) unchanged."""
    grid_max_columns: int | None = Field(1024, ge=16)
    """Lidar path with a grid (a ring field or recovered rows, and usable times): a scan
    of more columns than this keeps every k-th column, ``k = ceil(W / grid_max_columns)``,
    before extraction (:mod:`planodom.extraction.lidar.decimate`); None: every column.
    1024 (and 64 rows): the densest grid of the worlds every default was measured on, so
    none of them (nor KITTI 0005, organised path) changes; a denser unit's pixel normals
    over ``region_window`` columns were too short to grow regions on (RANSAC ran instead,
    at several times the cost). Measured (128 x 2048 lidar on worlds 1, 3, 41, 45, 47,
    6 mm, 60 epochs; rot deg / xy cm per epoch, ATE mm, all columns -> 1024 x 64):
    w1 0.0063 / 0.031 / 1.6 -> 0.0067 / 0.034 / 1.9; w3 0.0064 / 0.012 / 0.46 -> 0.0071
    / 0.022 / 0.37; w41 0.0011 / 0.036 / 2.5 -> 0.0014 / 0.027 / 1.8; w45 0.56 / 0.57 /
    261 -> 0.20 / 0.37 / 91; w47 0.044 / 133 / 9085 -> 0.0046 / 0.025 / 0.86; 2-3x the
    epochs per second; 64 x 2048 (w1, w47) rot 0.0065 -> 0.0079 and xy 0.021 -> 0.026 cm
    but ATE 2.0 -> 1.7 and 0.70 -> 0.82 mm, 1.4-1.6x the epochs per second. 512 columns
    was faster still (w45 36 mm ATE) but would change the 1024-column worlds."""
    grid_max_rows: int | None = Field(64, ge=4)
    """As ``grid_max_columns`` for the rows (beams): more rows than this keep every k-th
    row, ``k = ceil(H / grid_max_rows)``; None: every row. 64: as ``grid_max_columns``."""
    region_merge: Literal["grid", "reach"] = "grid"
    """Range image of a ringed scan (or rows with times): grid: coplanar pieces merge
    when near in the grid; reach: also when their bounding circles come within
    ``plane_gap_m``, as the image of an unorganised cloud does (a floor seen between the
    walls of a corridor, ahead and behind, is one plane; so are two coplanar walls 6 m
    apart). Not measured on the generalisation worlds yet: off by default."""

    @model_validator(mode="after")
    def _cross_checks(self) -> ExtractionConfig:
        """Fields that only make sense together (raises :class:`ConfigError`)."""
        pairs = (
            # (smaller field, larger field, why)
            ("rms_floor_m", "tolerance_floor_m", "a plane's RMS limit within its tolerance"),
            ("max_rms_sigma_factor", "member_sigma_factor", "the RMS test within membership"),
            ("trace_parallel_deg", "min_cross_angle_deg", "parallel traces never cross"),
            ("min_segment_points", "min_plane_points", "a trace fits in a plane"),
            ("min_gap_m", "plane_gap_m", "a scan-line run fits in one plane piece"),
        )
        if self.single_scanner_min_sweeps in (1, 2):
            raise ConfigError(
                "extraction.single_scanner_min_sweeps: must be 0 (off) or at least 3 (two "
                f"parallel lines are always coplanar), got {self.single_scanner_min_sweeps!r}"
            )
        for small, large, why in pairs:
            a, b = getattr(self, small), getattr(self, large)
            if a > b:
                raise ConfigError(
                    f"extraction.{small}: must be at most extraction.{large} ({b!r}: {why}), "
                    f"got {a!r}"
                )
        return self
