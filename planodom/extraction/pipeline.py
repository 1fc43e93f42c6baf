"""One epoch's points to oriented planes with covariance, confidence and support.

``extract(scan, config, twist, sensor_origins) -> ExtractionResult`` runs:

1. input checks (finite points, times, twist, origins; fewer than 3 points: no planes);
2. deskewing with the twist, when given and the scan has times (:mod:`.deskew`);
3. either the 2D-rig path (:mod:`.segments`, :mod:`.grouping`) or the 3D path
   (:mod:`.lidar`), which give candidate inlier sets;
   without a twist on a moving 2D-rig epoch (times spread over more than
   ``max_unskewed_span_s``) the grouping works in time windows of about one sweep (the
   odometry's first epochs have no motion yet): planes are fit per window, a wall must be
   found in ``min_unskewed_windows`` windows, one plane per wall is kept
   (:func:`drop_repeats`) with its (n, d) extrapolated to the reference time;
4. per candidate, a robust TLS fit on the points (:mod:`.fitting`), rejection of sets that
   are too small or too thin to be planes or whose normal is too uncertain
   (``max_normal_sigma_deg``), orientation, covariance, CPEF confidence
   (:mod:`.confidence`), support polygon and the majority true label.

Normal orientation: normals point to the side the sensor saw the plane from. With
``sensor_origins`` the viewpoint of a plane is the mean origin of the scanners that saw
its inliers (each origin carried to the reference time with the twist at the inliers'
mean time); without, it is ``(0, 0, viewpoint_height_m)`` in the base frame: a point above
the base origin, so that a ground plane through the base origin (a vehicle frame on the
ground, rig.yaml absent) still gets its normal up, and walls, whose distance from that
point equals their distance from the origin, face the vehicle. Planes through the
viewpoint itself fall back to "up" for near-horizontal ones
(:func:`.fitting.orientation_sign`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from planodom.config import ExtractionConfig
from planodom.errors import ConfigError, GeometryError
from planodom.extraction.confidence import cpef, cpef_batch, mean_incidence
from planodom.extraction.deskew import check_twist, deskew_points, se3_exp
from planodom.extraction.fitting import (
    PlaneFit,
    majority_label,
    make_support,
    orientation_sign,
    orientation_signs,
    robust_plane_fit,
    support_polygon,
    tls_covariance,
    tls_covariances,
)
from planodom.extraction.groupfit import fit_groups
from planodom.extraction.grouping import group_segments, required_traces
from planodom.extraction.lidar import lidar_candidates
from planodom.extraction.segments import split_scan_lines
from planodom.geometry import Plane, PlaneSupport
from planodom.scan import Scan

#: Largest coordinate (m) accepted; beyond it squares lose all precision.
MAX_COORDINATE_M = 1e6

MODES = ("auto", "rig2d", "lidar")


@dataclass(frozen=True, eq=False)
class ExtractionResult:
    """Planes of one epoch and how they were found.

    Attributes:
        planes: the extracted planes, largest support first.
        inliers: per plane, (K,) int64 indices into the scan's points.
        mode: "rig2d" or "lidar" (the path that ran), "empty" when no points.
        sigma_m: the noise sigma (m) the tolerances were scaled with.
        n_segments: straight segments found (2D path; 0 otherwise).
        n_candidates: candidate inlier sets before the plane tests.
        n_rejected: candidates rejected (too few points, too thin, seed lost).
        points: (N, 3) the points the planes were fit to (deskewed when a twist was given).
    """

    planes: list[Plane]
    inliers: list[np.ndarray]
    mode: str
    sigma_m: float
    n_segments: int = 0
    n_candidates: int = 0
    n_rejected: int = 0
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))


def _check_inputs(scan: Scan, sensor_origins) -> np.ndarray | None:
    pts = scan.points
    if not np.isfinite(pts).all():
        finite = np.isfinite(pts).all(axis=1)
        raise GeometryError(
            f"scan has {int(np.count_nonzero(~finite))} of {len(pts)} points with NaN or "
            "infinite coordinates (drop no-return beams before extraction)"
        )
    if len(pts) and max(pts.max(), -pts.min()) > MAX_COORDINATE_M:
        raise GeometryError(
            f"scan coordinates reach {np.abs(pts).max():.3g} m, beyond {MAX_COORDINATE_M:g} m"
        )
    if scan.t is not None and not np.all(np.isfinite(scan.t)):
        raise GeometryError("scan times t contain NaN or infinite values")
    if sensor_origins is None:
        return None
    try:
        org = np.asarray(sensor_origins, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise GeometryError(f"sensor_origins must be numbers, got {sensor_origins!r}") from exc
    if org.ndim == 1:
        org = org.reshape(1, -1)
    if org.ndim != 2 or org.shape[1] != 3 or not np.all(np.isfinite(org)):
        raise GeometryError(
            f"sensor_origins must be a finite (3,) or (R, 3) array, got shape {org.shape}"
        )
    if len(org) > 1:
        if scan.ring is None:
            raise GeometryError("per-ring sensor_origins need the scan's ring field")
        if len(scan.ring) and (scan.ring.min() < 0 or scan.ring.max() >= len(org)):
            raise GeometryError(
                f"ring ids {scan.ring.min()}..{scan.ring.max()} do not index the "
                f"{len(org)} sensor_origins"
            )
    return org


def choose_mode(scan: Scan, config: ExtractionConfig) -> str:
    """ "rig2d" or "lidar" for this scan under ``config.mode`` (see ExtractionConfig)."""
    if config.mode not in MODES:
        raise ConfigError(f"extraction.mode must be one of {MODES}, got {config.mode!r}")
    if config.mode != "auto":
        if config.mode == "rig2d" and scan.ring is None:
            raise GeometryError("extraction.mode 'rig2d' needs the scan's ring field")
        return config.mode
    if scan.ring is None:
        return "lidar"
    return "rig2d" if count_rings(scan.ring) <= config.max_rig_rings else "lidar"


def count_rings(ring: np.ndarray) -> int:
    """Number of distinct ring ids in ``ring`` (N,) (a counting pass for small ids)."""
    if len(ring) == 0:
        return 0
    lo, hi = int(ring.min()), int(ring.max())
    if lo >= 0 and hi < 1 << 16:
        return int(np.count_nonzero(np.bincount(ring)))
    return len(np.unique(ring))


def extract(
    scan: Scan,
    config: ExtractionConfig | None = None,
    twist: np.ndarray | None = None,
    sensor_origins: np.ndarray | None = None,
) -> ExtractionResult:
    """Planes of one epoch, with diagnostics (see :func:`extract_planes`)."""
    config = ExtractionConfig() if config is None else config
    org = _check_inputs(scan, sensor_origins)
    xi = check_twist(twist)
    if len(scan) < 3:
        return ExtractionResult([], [], "empty", config.range_noise_m, points=scan.points)
    mode = choose_mode(scan, config)
    pts = scan.points
    if xi is not None and scan.t is not None:
        pts = deskew_points(pts, scan.t, xi)

    if mode == "rig2d":
        segs, sigma = split_scan_lines(pts, scan.ring, scan.t, config)
        tol = max(config.member_sigma_factor * sigma, config.tolerance_floor_m)
        max_rms = max(config.max_rms_sigma_factor * sigma, config.rms_floor_m)
        windowed = unskewed_windows(scan, xi, config)
        seg_t0 = seg_t1 = None
        span = np.inf
        if windowed:
            tt = scan.t[segs.order]
            seg_t0, seg_t1 = tt[segs.starts], tt[segs.ends - 1]
            span = config.max_unskewed_span_s
            tol += config.max_unskewed_motion_m
            max_rms += 0.5 * config.max_unskewed_motion_m
        groups, rejected = group_segments(
            segs,
            tol,
            sigma,
            config.min_cross_angle_deg,
            config.max_seed_direction_error_deg,
            config.min_plane_points,
            max_rms,
            parallel_deg=config.trace_parallel_deg,
            step_m=config.trace_step_m,
            min_traces=required_traces(
                sigma, config.tolerance_floor_m, config.min_traces_high_noise
            ),
            seg_t0=seg_t0,
            seg_t1=seg_t1,
            max_span_s=span,
            gap_m=config.plane_gap_m,
            gap_ratio=config.gap_range_ratio,
            min_trace_points=config.min_segment_points,
            seed_floor_m=config.tolerance_floor_m
            + (config.max_unskewed_motion_m if windowed else 0.0),
        )
        n_segments = len(segs)
        repeats_tol = tol if windowed else None
        planes, inliers, n_rej = _rig_planes(
            groups, segs, scan, config, sigma, org, xi, repeats_tol
        )
        return _result(planes, inliers, mode, sigma, n_segments, len(groups), rejected + n_rej, pts)
    else:
        view = _scan_viewpoint(org, config)
        candidates, sigma = lidar_candidates(pts, config, scan.ring, view, scan.t)
        rejected, n_segments = 0, 0

    planes: list[Plane] = []
    inliers: list[np.ndarray] = []
    for cand in candidates:
        built = _build_plane(cand, pts, scan, config, sigma, org, xi)
        if built is None:
            rejected += 1
            continue
        planes.append(built[0])
        inliers.append(built[1])
    return _result(planes, inliers, mode, sigma, n_segments, len(candidates), rejected, pts)


def unskewed_windows(scan: Scan, xi: np.ndarray | None, config: ExtractionConfig) -> bool:
    """True when the 2D-rig path must work in time windows: no twist, and the scan's
    times spread over more than ``config.max_unskewed_span_s`` (see ExtractionConfig)."""
    if xi is not None or scan.t is None or len(scan.t) == 0:
        return False
    return float(np.ptp(scan.t)) > config.max_unskewed_span_s


def drop_repeats(
    n: np.ndarray,
    d: np.ndarray,
    cen: np.ndarray,
    rad: np.ndarray,
    tm: np.ndarray,
    tol_m: float,
    config: ExtractionConfig,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Keep one plane per wall among planes fit in different time windows (no deskew).

    Planes are visited by the mean time of their inliers, earliest first (closest to the
    reference time, so least displaced by the motion); a plane is dropped when a kept one
    has its normal within ``unskewed_repeat_deg`` (either sign), its offset within
    ``tol_m + max_unskewed_speed_m_s * dt`` (dt: the difference of their mean times) and
    supports that overlap (bounding circles about the centroids, grown by the same
    allowance). A plane found in fewer than ``min_unskewed_windows`` windows is dropped.
    The (n, d) of a kept plane are extrapolated to the reference time t = 0 from its
    repeats: a straight-line fit of each normal component and of the offset against the
    windows' mean times (constant velocity), normal renormalised and oriented as before.

    Args:
        n: (P, 3) oriented unit normals. d: (P,) offsets (m). cen: (P, 3) support centroids
        (m). rad: (P,) support radii about them (m). tm: (P,) mean inlier times (s).

    Returns:
        Indices (K,) of the kept planes (ascending), their normals (K, 3) and offsets (K,).
    """
    P = len(n)
    if P < 2:
        keep = np.arange(P) if config.min_unskewed_windows <= 1 else np.zeros(0, np.int64)
        return keep, n[keep], d[keep]
    order = np.argsort(tm, kind="stable")
    cos_tol = np.cos(np.radians(config.unskewed_repeat_deg))
    c = n @ n.T
    sgn = np.where(c < 0, -1.0, 1.0)
    allow = tol_m + config.max_unskewed_speed_m_s * np.abs(tm[:, None] - tm[None, :])
    same = (np.abs(c) >= cos_tol) & (np.abs(sgn * d[:, None] - d[None, :]) <= allow)
    dist = np.linalg.norm(cen[:, None] - cen[None, :], axis=2)
    same &= dist <= rad[:, None] + rad[None, :] + allow
    np.fill_diagonal(same, False)
    seen = same.sum(axis=1)
    kept: list[int] = []
    for i in order:
        if seen[i] + 1 < config.min_unskewed_windows:
            continue
        if not (kept and np.any(same[i, kept])):
            kept.append(int(i))
    kept.sort()
    keep = np.array(kept, dtype=np.int64)
    n_out, d_out = n[keep].copy(), d[keep].copy()
    for k, i in enumerate(keep):
        idx = np.concatenate([[i], np.flatnonzero(same[i])])
        t = tm[idx]
        if len(idx) < 2 or np.ptp(t) <= 0:
            continue
        # Least-squares line y = a + b t per component; a is the value at t = 0.
        y = sgn[i, idx][:, None] * np.column_stack([n[idx], d[idx]])  # (K, 4)
        tc = t - t.mean()
        slope = tc @ (y - y.mean(axis=0)) / (tc @ tc)
        at0 = y.mean(axis=0) - slope * t.mean()
        norm = float(np.linalg.norm(at0[:3]))
        if not norm > 0:
            continue
        s = 1.0 if at0[:3] @ n[i] >= 0 else -1.0  # the plane's own orientation
        n_out[k] = s * at0[:3] / norm
        d_out[k] = s * at0[3] / norm
    return keep, n_out, d_out


def _result(planes, inliers, mode, sigma, n_segments, n_candidates, rejected, pts):
    order = np.argsort([-len(i) for i in inliers], kind="stable")
    return ExtractionResult(
        planes=[planes[i] for i in order],
        inliers=[inliers[i] for i in order],
        mode=mode,
        sigma_m=sigma,
        n_segments=n_segments,
        n_candidates=n_candidates,
        n_rejected=rejected,
        points=pts,
    )


def _rig_planes(groups, segs, scan, config, sigma, org, xi, repeats_tol=None):
    """Planes of the 2D-rig groups of segments: robust refit of all groups at once
    (:func:`.groupfit.fit_groups`), the plane tests, covariances, orientations and
    confidences of all groups at once, then a :class:`Plane` per kept group with its
    support. With ``repeats_tol`` (m; time windows without deskew) one plane per wall is
    kept among the windows' (:func:`drop_repeats`) before the planes are built. Returns
    planes, inliers (scan indices) and the number of groups rejected (too few inliers,
    too thin, too uncertain a normal, a repeat)."""
    G = len(groups)
    if G == 0:
        return [], [], 0
    view0 = np.array([0.0, 0.0, config.viewpoint_height_m])
    fits = fit_groups(segs, groups, config.inlier_sigma_factor, view0 if org is None else None)
    cnt = np.maximum(fits.count, 1).astype(np.float64)
    evals = fits.evals[:, ::-1]  # descending: l1, l2, l3
    evecs = fits.evecs[:, :, ::-1]  # columns e1, e2, n
    width = 2.0 * np.sqrt(np.maximum(evals[:, 1], 0.0) / cnt)
    rms = np.sqrt(np.maximum(evals[:, 2], 0.0) / cnt)
    normals = evecs[:, :, 2]
    offsets = -np.einsum("gi,gi->g", normals, fits.centroid)
    covs = tls_covariances(evals, evecs, fits.centroid, fits.count, config.covariance_sigma_floor_m)
    keep = (fits.count >= max(config.min_plane_points, 3)) & (width >= config.min_plane_width_m)
    keep &= ~too_uncertain(covs, config)
    kept = np.flatnonzero(keep)
    idx_all = segs.order[fits.inliers]
    kp_all = segs.points[fits.inliers]
    views = np.broadcast_to(view0, (G, 3)).copy()
    incidence = fits.incidence.copy()
    if org is not None:
        for g in kept:
            a, b = fits.bounds[g], fits.bounds[g + 1]
            views[g] = _viewpoint(idx_all[a:b], scan, org, xi, config)
            incidence[g] = mean_incidence(kp_all[a:b], views[g], normals[g])
    signs = orientation_signs(normals, offsets, fits.centroid, views)
    conf = cpef_batch(
        rms, max(sigma, config.covariance_sigma_floor_m), fits.count, width, incidence,
        config.confidence_points_ref, config.confidence_width_ref_m,
    )  # fmt: skip
    n_or = signs[:, None] * normals
    d_or = signs * offsets
    if repeats_tol is not None and len(kept):
        tm = np.add.reduceat(scan.t[idx_all], fits.bounds[:-1]) / cnt
        # Support radius: the farthest run end from the centroid (the polygon's vertices
        # are among the run ends).
        ends = fits.is_end
        gid = np.repeat(np.arange(G), np.diff(fits.bounds))[ends]
        r_end = np.linalg.norm(kp_all[ends] - fits.centroid[gid], axis=1)
        rad = np.zeros(G)
        np.maximum.at(rad, gid, r_end)
        sel, n_k, d_k = drop_repeats(
            n_or[kept], d_or[kept], fits.centroid[kept], rad[kept], tm[kept], repeats_tol,
            config,
        )  # fmt: skip
        kept = kept[sel]
        n_or[kept], d_or[kept] = n_k, d_k
    planes, inliers = [], []
    for g in kept:
        a, b = fits.bounds[g], fits.bounds[g + 1]
        idx = idx_all[a:b]
        fit = PlaneFit(
            fits.inliers[a:b], normals[g], float(offsets[g]), fits.centroid[g], evals[g],
            evecs[g],
        )  # fmt: skip
        plane = Plane(
            normal=n_or[g],
            offset=float(d_or[g]),
            covariance=covs[g],
            confidence=float(conf[g]),
            support=PlaneSupport(
                fits.centroid[g].copy(),
                support_polygon(kp_all[a:b][fits.is_end[a:b]], fit),
                int(fits.count[g]),
            ),
            truth_id=majority_label(None if scan.label is None else scan.label[idx]),
        )
        planes.append(plane)
        inliers.append(idx)
    return planes, inliers, G - len(kept)


def too_uncertain(cov: np.ndarray, config: ExtractionConfig) -> np.ndarray:
    """True where a (..., 4, 4) (n, d) covariance puts the normal's 1-sigma error above
    ``config.max_normal_sigma_deg`` (a bool array of the leading shape)."""
    var_n = np.trace(cov[..., :3, :3], axis1=-2, axis2=-1)
    return var_n > np.radians(config.max_normal_sigma_deg) ** 2


def _scan_viewpoint(org: np.ndarray | None, config: ExtractionConfig) -> np.ndarray:
    """(3,) one viewpoint for the whole scan: the mean sensor origin, or above the origin."""
    if org is None:
        return np.array([0.0, 0.0, config.viewpoint_height_m])
    return org.mean(axis=0)


def _viewpoint(
    idx: np.ndarray, scan: Scan, org: np.ndarray | None, xi: np.ndarray | None, config
) -> np.ndarray:
    """(3,) where the inliers ``idx`` were seen from, in the reference-time base frame."""
    if org is None:
        return np.array([0.0, 0.0, config.viewpoint_height_m])
    view = org[0] if len(org) == 1 else org[scan.ring[idx]].mean(axis=0)
    if xi is not None and scan.t is not None:
        rot, trans = se3_exp(xi, np.array([float(scan.t[idx].mean())]))
        view = rot.apply(view[None])[0] + trans[0]
    return view


def _build_plane(
    cand: np.ndarray,
    pts: np.ndarray,
    scan: Scan,
    config: ExtractionConfig,
    sigma: float,
    org: np.ndarray | None,
    xi: np.ndarray | None,
) -> tuple[Plane, np.ndarray] | None:
    if len(cand) < config.min_plane_points:
        return None
    fit = robust_plane_fit(pts[cand], config.inlier_sigma_factor)
    if fit is None or fit.n_points < config.min_plane_points:
        return None
    if fit.width < config.min_plane_width_m:
        return None
    cov = tls_covariance(fit, config.covariance_sigma_floor_m)
    if too_uncertain(cov, config):
        return None
    idx = cand[fit.inliers]
    inl = pts[idx]
    view = _viewpoint(idx, scan, org, xi, config)
    sign = orientation_sign(fit.normal, fit.offset, fit.centroid, view)
    conf = cpef(
        fit.rms,
        max(sigma, config.covariance_sigma_floor_m),
        fit.n_points,
        fit.width,
        fit.normal,
        inl,
        view,
        config.confidence_points_ref,
        config.confidence_width_ref_m,
    )
    plane = Plane(
        normal=sign * fit.normal,
        offset=sign * fit.offset,
        covariance=cov,
        confidence=conf,
        support=make_support(inl, fit),
        truth_id=majority_label(None if scan.label is None else scan.label[idx]),
    )
    return plane, idx


def extract_planes(
    scan: Scan,
    config: ExtractionConfig | None = None,
    twist: np.ndarray | None = None,
    sensor_origins: np.ndarray | None = None,
) -> list[Plane]:
    """The planes of one epoch: oriented normal, offset, covariance, CPEF weight, support.

    Args:
        scan: the epoch's points (base frame at each point's time), with ``ring`` (a 2D
            rig: few rings; a lidar: many) and ``t`` when known, ``label`` in simulation.
        config: thresholds (:class:`planodom.config.ExtractionConfig`); defaults if None.
        twist: optional (6,) constant body twist ``(wx, wy, wz, vx, vy, vz)`` (rad/s, m/s)
            over the epoch; points are first brought to the reference time with it.
        sensor_origins: optional sensor positions in the base frame, metres: (3,) one for
            all points, or (R, 3) indexed by ring id. Used to orient normals.

    Returns:
        Planes, largest support first. Each has a unit normal pointing towards the
        sensor, ``d`` (n . p + d = 0), a (4, 4) covariance of (n, d) (rank 3,
        :mod:`planodom.extraction.fitting`), a CPEF confidence in (0, 1]
        (:mod:`planodom.extraction.confidence`), support (centroid, convex polygon in the
        plane, point count) and ``truth_id`` (majority inlier label, -1 without labels).
        Empty input or fewer than 3 points give no planes.

    Raises:
        GeometryError: NaN / infinite / absurdly large coordinates or times, a malformed
            twist or sensor_origins.
        ConfigError: an unknown ``config.mode``.
    """
    return extract(scan, config, twist, sensor_origins).planes
