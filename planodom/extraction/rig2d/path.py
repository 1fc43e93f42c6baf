"""The 2D-rig path: scan lines to segments, traces, groups, fits and planes.

1. split the scan lines into straight segments (:mod:`.segments`, :mod:`.scanlines`);
2. merge each scanner's segments over its sweeps into traces and group traces of
   different scanners into planes (:mod:`.traces`, :mod:`.grouping`), and, with
   ``single_scanner_min_sweeps``, one scanner's lines of several sweeps
   (:mod:`.sweeplines`);
3. with a sensor origin per ring and ``extraction.own_scan_plane`` on (off by default),
   take a ring whose sensor lies on a group's plane out of the group, a tilted scanner's
   own scan plane taken for a wall (:func:`without_own_scan_plane`), or drop the group;
4. refit every group robustly on its points (:mod:`.groupfit`);
5. build the planes (:func:`planodom.extraction.planes.builder.build_planes`);
6. with ``single_scanner_rate_sigma_deg_s`` / ``..._speed_sigma_mps`` (off), widen the
   covariance of one ring's planes by the twist's error (:mod:`.onescanner`).

Without a twist on a moving epoch, all of this works in time windows (:mod:`.windows`);
with one, the tolerances grow by the smear the twist's uncertainty leaves
(``twist_rate_sigma_deg_s``, ``twist_speed_sigma_mps``, :func:`.windows.twist_smear`).
"""

from __future__ import annotations

import numpy as np

from planodom.angles import radians, sin_of_degrees
from planodom.config import ExtractionConfig
from planodom.extraction.epoch import Epoch, PathResult
from planodom.extraction.noise import member_tolerance, rms_limit
from planodom.extraction.planes.builder import PlaneFits, build_planes
from planodom.extraction.rig2d import coplanargroups, onescanner, sparsewindows, windows
from planodom.extraction.rig2d.groupfit import plane_fits
from planodom.extraction.rig2d.grouping import GroupingParams
from planodom.extraction.rig2d.groups import group_segments
from planodom.extraction.rig2d.narrow import narrow_groups
from planodom.extraction.rig2d.segments import Segments, split_scan_lines
from planodom.extraction.rig2d.sweeptilt import tilted_rings


def rig2d_planes(epoch: Epoch, config: ExtractionConfig) -> PathResult:
    """The planes of a 2D-rig epoch (module docstring)."""
    scan = epoch.scan
    assert scan.ring is not None  # the pipeline sends scans without rings to the lidar path
    segs, sigma = split_scan_lines(epoch.points, scan.ring, scan.t, config, epoch.origins)
    tol, max_rms = member_tolerance(config, sigma), rms_limit(config, sigma)
    seed_floor = config.tolerance_floor_m
    tw = config.time_windows
    windowed = windows.is_windowed(scan, epoch.twist, tw)
    seg_times, span, full_min = None, np.inf, config.min_plane_points
    if windowed:
        seg_times = windows.segment_times(scan, segs)
        tw = windows.for_epoch(tw, scan, segs)
        config = windows.per_window(config, tw)  # a wall's points over its windows
        span = tw.span_s
        tol, max_rms, seed_floor = windows.windowed_tolerances(tol, max_rms, seed_floor, tw)
    elif epoch.twist is not None:
        if config.single_scanner_min_sweeps and scan.t is not None:
            seg_times = windows.segment_times(scan, segs)  # which sweep a trace is of
        rate = float(radians(config.twist_rate_sigma_deg_s))
        smear = windows.twist_smear(scan, epoch.points, rate, config.twist_speed_sigma_mps)
        tol, max_rms, seed_floor = windows.widened(tol, max_rms, seed_floor, smear)
    seed_normal_deg = max(config.max_seed_normal_error_deg, config.narrow_seed_last_deg)
    params = GroupingParams(
        tol_m=float(tol),
        sigma_m=float(sigma),
        sin_min_cross=sin_of_degrees(config.min_cross_angle_deg),
        max_seed_err_rad=float(radians(config.max_seed_direction_error_deg)),
        min_points=float(config.min_plane_points),
        max_rms_m=float(max_rms),
        min_trace_points=int(config.min_segment_points),
        seed_floor_m=float(seed_floor),
        gap_m=float(config.plane_gap_m),
        gap_ratio=float(config.gap_range_ratio),
        max_span_s=float(span),
        max_seed_normal_err_rad=float(radians(seed_normal_deg)),
        min_sweep_lines=int(config.single_scanner_min_sweeps),
        parallel_rad=float(radians(config.trace_parallel_deg)),
        seed_spans_gap=bool(config.seed_spans_gap),
        span_min_nz=_level_cosine(config.seed_spans_gap_max_tilt_deg),
        exclusive_seeds=bool(config.exclusive_seeds),
        narrow_last=config.narrow_seed_last_deg > 0,
        gap_bridge=config.gap_bridge == "predicted",
    )
    groups, n_lost = group_segments(
        segs, params, config.trace_parallel_deg, config.trace_step_m, seg_times
    )
    n_groups = len(groups)
    origins = epoch.origins if epoch.origins is not None and len(epoch.origins) > 1 else None
    if origins is not None and config.own_scan_plane == "dropped":
        sin_parallel = float(np.sin(params.parallel_rad))
        groups = [g for g in groups if not spans_own_scan_plane(segs, g, sin_parallel, origins)]
    elif origins is not None and config.own_scan_plane == "trimmed":
        trimmed = [without_own_scan_plane(segs, g, params, origins) for g in groups]
        groups = [g for g in trimmed if g is not None]
    if config.sweep_tilt == "trimmed" and epoch.twist is not None and scan.t is not None:
        first, last = windows.segment_times(scan, segs)
        mid, factor = 0.5 * (first + last), config.member_sigma_factor
        tilted = [without_sweep_tilt(segs, g, params, mid, factor) for g in groups]
        groups = [g for g in tilted if g is not None]
    n_lost += n_groups - len(groups)
    if not groups:
        return PathResult([], [], sigma, len(segs), 0, n_lost)
    groups, fits, n_dropped = _refit_groups(segs, groups, epoch, config, params, windowed)
    n_lost += n_dropped
    if fits is None:
        return PathResult([], [], sigma, len(segs), 0, n_lost)
    adjust = None
    if windowed:
        allowed = None
        if tw.sparse_windows_determined:  # the member tolerance before the window's motion
            lim_n, lim_d = config.max_normal_sigma_deg, member_tolerance(config, sigma)
            allowed = sparsewindows.determined(fits, sigma, full_min, lim_n, lim_d)
        adjust = windows.keep_one_per_wall(fits, epoch.points, scan, tol, tw, allowed)
    narrow = None
    if config.narrow_seed_last_deg > 0:  # which planes the narrow seeds gave (.narrow)
        narrow = narrow_groups(segs, groups, params.sin_min_cross)
    planes, inliers, n_rejected = build_planes(fits, epoch, sigma, config, adjust, narrow)
    planes = onescanner.widened_planes(planes, inliers, epoch, config)
    return PathResult(planes, inliers, sigma, len(segs), len(groups), n_lost + n_rejected)


def _refit_groups(
    segs: Segments, groups: list[np.ndarray], epoch: Epoch, config: ExtractionConfig,
    params: GroupingParams, windowed: bool,
) -> tuple[list[np.ndarray], PlaneFits | None, int]:  # fmt: skip
    """The groups' robust refits (:func:`_group_fits`), without the groups whose refit lost
    its crossing (``refit_keeps_cross``) and, deskewed, with the groups of one plane joined
    (``merge_coplanar_groups``, :mod:`.coplanargroups`): the groups kept, their fits (None
    when none is left) and the number dropped."""
    fits, dropped = _group_fits(segs, groups, epoch, config), 0
    if config.refit_keeps_cross:
        ring = epoch.scan.ring
        assert ring is not None
        lost = [lost_cross(segs, g, ring[fits.members(k)], config.min_segment_points)
                for k, g in enumerate(groups)]  # fmt: skip
        if any(lost):
            groups = [g for g, drop in zip(groups, lost, strict=True) if not drop]
            dropped = len(lost) - len(groups)
            if not groups:
                return groups, None, dropped
            fits = _group_fits(segs, groups, epoch, config)
    if config.merge_coplanar_groups and not windowed:
        merged = coplanargroups.merged_groups(groups, fits, params.tol_m, params.max_rms_m)
        if merged is not None:
            groups, fits = merged, _group_fits(segs, merged, epoch, config)
    return groups, fits, dropped


def without_own_scan_plane(
    segs: Segments, group: np.ndarray, params: GroupingParams, origins: np.ndarray
) -> np.ndarray | None:
    """``group`` (K,) segment indices without the segments of the rings whose sensor lies
    on the group's plane (:func:`on_plane_rings`: two or more of the ring's segments in
    it, its rays parallel to it within ``params.parallel_rad``), or None when what is left
    is not a plane by the grouping's own rules (:mod:`.grouping`): segments of two rings
    crossing at ``params.sin_min_cross`` or more, ``params.min_points`` points and an RMS
    residual about their plane (least squares over the segments' moments) within
    ``params.max_rms_m``. The group is returned unchanged (the same array) when no ring
    lies on its plane. ``origins`` (R, 3) m: each ring's sensor origin, base frame.

    A scanner's own scan plane holds its rays and its lines on every surface it sees; such
    a group is that ring's lines plus a short trace of another ring that seeded it, and
    without the ring it is not a plane (world 32 at 2 cm: odometry ATE 3.23 -> 0.84 m
    over 200 epochs, world 2 3.08 -> 1.27 m). A real floor or wall seen by several rings,
    one of them at grazing incidence from far away, loses only that ring's lines and is
    refit without them (world 46 at 2 cm keeps a 6376-point floor seen by four rings that
    :func:`spans_own_scan_plane` drops whole). A wall seen by one other ring only, in
    parallel lines of its sweeps, still goes: its tilt about those lines is then set by
    the grazing ring alone, which its own scan plane would set the same way (counting a
    ring only with two distinct lines, traces, in the group kept such walls but also
    world 2's ghost: one sparse line of a ring on a wall, its sensor on a plane through
    another ring's floor lines 19.6 deg off the floor; ATE 1.27 -> 3.08 m). No new
    threshold: the parallelism is ``trace_parallel_deg``, the rest the grouping's.
    """
    bad = on_plane_rings(segs, group, float(np.sin(params.parallel_rad)), origins)
    if not bad:
        return group
    return without_rings(segs, group, bad, params)


def without_sweep_tilt(
    segs: Segments, group: np.ndarray, params: GroupingParams, seg_times: np.ndarray,
    factor: float,
) -> np.ndarray | None:  # fmt: skip
    """``group`` (K,) segment indices without the rings whose lines of several sweeps are
    displaced across the group's plane more than within it (:func:`.sweeptilt.tilted_rings`:
    ``seg_times`` (S,) s the segments' mean times, noise ``factor`` times
    ``params.sigma_m``), or None
    when what is left is not a plane (:func:`without_rings`); the same array when none is
    (``extraction.sweep_tilt: trimmed``)."""
    scatter = _moments(segs, group)[1]
    normal = np.linalg.eigh(scatter)[1][:, 0]
    bad = tilted_rings(segs, group, normal, seg_times, params.sigma_m, factor, params.tol_m)
    if not bad:
        return group
    return without_rings(segs, group, bad, params)


def without_rings(
    segs: Segments, group: np.ndarray, bad: list[int], params: GroupingParams
) -> np.ndarray | None:
    """``group`` (K,) segment indices without the segments of rings ``bad``, or None when
    what is left is not a plane by the grouping's own rules (:func:`without_own_scan_plane`)."""
    rest = group[~np.isin(segs.ring[group], bad)]
    if len(np.unique(segs.ring[rest])) < 2:
        return None
    n_points = float(segs.count[rest].sum())
    if n_points < params.min_points:
        return None
    scatter = _moments(segs, rest)[1]
    if np.sqrt(max(float(np.linalg.eigvalsh(scatter)[0]), 0.0) / n_points) > params.max_rms_m:
        return None
    u, ring = segs.direction[rest], segs.ring[rest]
    sines = np.linalg.norm(np.cross(u[:, None, :], u[None, :, :]), axis=-1)
    crossing = (sines >= params.sin_min_cross) & (ring[:, None] != ring[None, :])
    return rest if bool(crossing.any()) else None


def on_plane_rings(
    segs: Segments, group: np.ndarray, sin_parallel: float, origins: np.ndarray
) -> list[int]:
    """The rings of ``group`` (K,) segment indices with two or more segments in it whose
    sensor origin (``origins`` (R, 3) m, base frame, by ring) lies on the group's plane
    (least squares over its segments' moments): the origin's distance to the plane is at
    most ``sin_parallel`` times the ring's mean range to those segments (weighted by
    points), i.e. the ring's rays are parallel to the plane within that angle on average.
    Measured: a scanner's own plane lies at 0-1.5 deg from its ring's rays (world 32, 2
    cm and 6 mm), real planes that a ring cuts in two directions from 7 deg (worlds 4, 16,
    18 at 2 cm)."""
    rings = segs.ring[group]
    c, scatter = _moments(segs, group)
    normal = np.linalg.eigh(scatter)[1][:, 0]
    bad = []
    for r in np.unique(rings):
        mine = group[rings == r]
        if len(mine) < 2 or r >= len(origins):
            continue
        rng = np.linalg.norm(segs.centroid[mine] - origins[r], axis=1)
        w = segs.count[mine].astype(np.float64)
        if abs(normal @ (origins[r] - c)) <= sin_parallel * float(w @ rng / w.sum()):
            bad.append(int(r))
    return bad


def _moments(segs: Segments, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centroid (3,) m and scatter (3, 3) m^2 of the points of segments ``idx`` (K,), from
    their moments (the grouping's compiled ``_plane_of`` does the same over traces)."""
    n_k = segs.count[idx].astype(np.float64)
    c = (n_k[:, None] * segs.centroid[idx]).sum(axis=0) / n_k.sum()
    dc = segs.centroid[idx] - c
    return c, segs.scatter[idx].sum(axis=0) + np.einsum("k,ki,kj->ij", n_k, dc, dc)


def spans_own_scan_plane(
    segs: Segments, group: np.ndarray, sin_parallel: float, origins: np.ndarray | None
) -> bool:
    """Whether ``group`` (K,) segment indices is the scan plane of one of its rings: two or
    more of the ring's segments in it, and the ring's rays to them (from its sensor origin,
    ``origins`` (R, 3) m, base frame, by ring; None, as for one origin for all: never)
    parallel to the group's plane (least squares over its segments' moments) within the
    angle of sine ``sin_parallel`` (``trace_parallel_deg``), on average over the ring's
    points (the origin's distance to the plane over the segments' mean range).

    A real plane never holds the scanner that sees it (its points would be at grazing
    incidence); a scanner's own plane holds its rays and its lines on every surface (the
    two walls of a corridor, the floor, the ceiling). Fixed in the base frame, such a
    plane reports no motion along its normal: on world 32 at 2 cm one grown from a short
    trace of another scanner took the odometry's along-row motion to 0.01 m a step
    instead of 0.07 m for 60 epochs. Measured: such planes lie at 0-1.5 deg from their
    ring's rays (world 32, 2 cm and 6 mm), real planes that a ring cuts in two directions
    from 7 deg (worlds 4, 16, 18 at 2 cm); a bound of ``min_cross_angle_deg`` (10 deg)
    dropped the floor of world 18 (ATE 1.16 -> 3.19 m over 200 epochs).
    """
    if origins is None or len(origins) < 2:
        return False
    return bool(on_plane_rings(segs, group, sin_parallel, origins))


def lost_cross(
    segs: Segments, group: np.ndarray, inlier_rings: np.ndarray, min_points: int
) -> bool:
    """True when the group's segments are of two or more rings but its refit's inliers
    hold ``min_points`` or more in one ring at most: the crossing line is gone, and the
    tilt about the remaining line rests on a few stray points, its stated normal sigma
    right for their noise but not for which surface they are on
    (``extraction.refit_keeps_cross``).

    World 32 at 6 mm, epoch 71: the grouping joins one line of ring 3 and 15 points of
    ring 2, the refit (scale 0.7 mm, ring 3's) keeps 1 of them; the plane is 0.74 deg from
    the previous epoch's against 0.012 deg stated, and step 71 is 0.104 m off (0.004 m
    with the group dropped). Off by default, measured (streaming odometry, 200 epochs, ATE): with
    ``own_scan_plane: dropped`` world 32 at 6 mm 2.89 -> 0.21 m (whole lap 3.67 -> 0.33
    m), the 15 other runs (worlds 0-20 even and 32 at 2 cm, 0, 2 and 16 at 6 mm) within
    9.3 mm; but with batch smoothing and loops world 32 at 6 mm stays at 3.6 m (3.55 ->
    3.60; main 0.14), and with ``kept`` (the default) world 32 gets worse: 2.23 -> 2.38 m
    at 6 mm, batch + loops 2.80 -> 3.09 m at 2 cm.

    Args:
        segs: the epoch's segments. group: (S_g,) its segment indices.
        inlier_rings: (K,) the ring of each inlier of the group's refit.
        min_points: the fewest inliers a ring needs to count (``min_segment_points``).
    """
    if len(np.unique(segs.ring[group])) < 2:
        return False  # one scanner's lines of several sweeps: no crossing to lose
    _, counts = np.unique(inlier_rings, return_counts=True)
    return int(np.count_nonzero(counts >= min_points)) < 2


def _group_fits(
    segs: Segments, groups: list[np.ndarray], epoch: Epoch, config: ExtractionConfig
) -> PlaneFits:
    """The robust refits of the groups as builder input (:func:`.groupfit.plane_fits`);
    the incidence is computed in the refit when the viewpoint is the same for all (no
    sensor origins)."""
    view0 = np.array([0.0, 0.0, config.viewpoint_height_m])
    return plane_fits(
        segs, groups, config.inlier_sigma_factor, view0 if epoch.origins is None else None
    )


def _level_cosine(max_tilt_deg: float) -> float:
    """The smallest |n_z| of a plane within ``max_tilt_deg`` of level; 0 at 90 deg (any)."""
    return 0.0 if max_tilt_deg >= 90.0 else float(np.cos(radians(max_tilt_deg)))
