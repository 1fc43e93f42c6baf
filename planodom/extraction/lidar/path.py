"""The lidar (3D) path: candidate inlier sets, fits and planes.

1. candidate inlier sets:

   - a scan with ``ring``: region growing on the range image, or the seeded RANSAC loop
     (:func:`.candidates.lidar_candidates`);
   - a scan without ``ring`` (an unorganised cloud) and ``unorganised == "rows"``: the
     scan lines are recovered (:func:`.rows.scan_rows`, seen from the sensor origin).
     With recorded per-point times, rows and times are what a ring field gives: the
     recovered rows are taken as the ring (the first case). Without times, or with times
     recovered from the azimuth (:class:`.sweep.AzimuthTimedScan`: they deskew the
     points; the rows are those of the raw cloud, the columns the azimuth bins of the
     deskewed points), planes grow on a range
     image of square angular pixels (:func:`.organised.organised_candidates`), whose
     columns come from the azimuth and average several points: for a sparse lidar (16
     beams 2 deg apart) those pixels are 5-10 native columns wide and lose the small
     planes (measured: 9 planes of an indoor lidar16 scan against 20 with its times and
     19 true surfaces). RANSAC when no rows are found or they give no plane (a cloud
     that is not a spinning lidar's);
   - a scan with ``ring`` but no usable times (no ``t`` field, or all equal) and
     ``untimed_rings == "rows"``: its ring range image has no columns, so planes grow on
     the square-pixel image of the rings ordered by elevation
     (:func:`.rows.ring_scan_rows`, :func:`.organised.organised_candidates`), as for
     recovered rows; RANSAC when the rings are not scan lines or give no plane. The
     RANSAC loop on such scans (the rule before) measured on libwave's HDL-32E sweeps
     (ring, no time): 1.64 deg and 13 cm rms per epoch on a still sensor against 0.22 deg
     and 0.6 cm, and 0.10 against 0.58-0.94 of KISS-ICP's speed on the parking-lot sweeps;
2. a fit of each candidate: robust TLS (:func:`planodom.extraction.planes.fit.
   robust_plane_fits`, iterated 1.4826 MAD inlier selection) for the first, plain TLS of
   the members for the organised candidates (their points were already selected within
   the member tolerance of a plane grown on the image; trimming by the MAD would drop the
   outer scan lines of a plane whose lasers carry range biases);
3. the planes (:func:`planodom.extraction.planes.builder.build_planes`), with the number of
   scan lines each spans.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction.epoch import Epoch, PathResult
from planodom.extraction.lidar.agreement import cutting_planes, point_normals
from planodom.extraction.lidar.candidates import lidar_candidates
from planodom.extraction.lidar.decimate import kept_points, subset_scan
from planodom.extraction.lidar.grid import distinct_per_block, grid_indices
from planodom.extraction.lidar.organised import organised_candidates
from planodom.extraction.lidar.reuse import Segmentation, remembered, reused
from planodom.extraction.lidar.rows import ring_scan_rows, scan_rows
from planodom.extraction.lidar.sweep import AzimuthTimedScan
from planodom.extraction.memo import identity_memo, read_only
from planodom.extraction.planes.builder import Adjust, PlaneFits, build_planes
from planodom.extraction.planes.fit import robust_plane_fits, tls_fit
from planodom.scan import Scan


def lidar_planes(epoch: Epoch, config: ExtractionConfig) -> PathResult:
    """The planes of a 3D scan (module docstring)."""
    scan = epoch.scan
    view = epoch.scan_viewpoint(config.viewpoint_height_m)
    if scan.ring is None and config.unorganised == "rows":
        origin = np.zeros(3) if epoch.origins is None else epoch.origins.mean(axis=0)
        # Rows of the raw cloud (its file order and elevations are the sensor's); the
        # image's columns are azimuth bins of the deskewed points (bins several native
        # columns wide; bins of the raw azimuths measured no better on a lidar world).
        found = _scan_rows(scan.points, *(float(v) for v in origin))
        if found is not None:
            rows = found[0]
            if not isinstance(scan, AzimuthTimedScan):
                native = _native_planes(epoch, rows, view, config)
                if native is not None:
                    return native
            organised = _organised_planes(epoch, rows, origin, config)
            if organised is not None:  # rows that gave no plane were no lidar's rows
                return organised
    elif scan.ring is not None and _untimed_rings(scan.ring, scan.t, config):
        origin = np.zeros(3) if epoch.origins is None else epoch.origins.mean(axis=0)
        ring_rows = _ring_scan_rows(scan.points, scan.ring, *(float(v) for v in origin))
        if ring_rows is not None:
            organised = _organised_planes(epoch, ring_rows, origin, config)
            if organised is not None:
                return organised
    return _candidate_planes(epoch, scan.ring, view, config)


def _organised_planes(
    epoch: Epoch, rows: np.ndarray, origin: np.ndarray, config: ExtractionConfig
) -> PathResult | None:
    """The planes grown on the square-pixel image of ``epoch``'s points with ``rows`` (N,)
    int64 seen from ``origin`` (3,) m (:func:`.organised.organised_candidates`, plain TLS
    fits); None when there is none (RANSAC decides)."""
    organised = organised_candidates(epoch.points, rows, origin, config)
    fits = member_fits(organised.candidates, epoch.points, rows)
    planes, inliers, n_rejected = build_planes(fits, epoch, organised.sigma_m, config)
    if not planes:
        return None
    n_cand = len(organised.candidates)
    return PathResult(planes, inliers, organised.sigma_m, 0, n_cand, n_rejected)


def _untimed_rings(ring: np.ndarray, t: np.ndarray | None, config: ExtractionConfig) -> bool:
    """Whether a scan's ``ring`` (N,) and times ``t`` (N,) s give a range image without
    columns (no usable times) and ``untimed_rings`` asks for the rings' square-pixel
    image."""
    if not config.range_image or config.untimed_rings != "rows":
        return False
    return grid_indices(ring, t)[1] is None


@identity_memo
def _ring_scan_rows(
    points: np.ndarray, ring: np.ndarray, x: float, y: float, z: float
) -> np.ndarray | None:
    """:func:`.rows.ring_scan_rows` seen from ``(x, y, z)`` m, read-only and memoised
    (:mod:`planodom.extraction.memo`): they depend on the raw scan alone."""
    rows = ring_scan_rows(points, ring, np.array([x, y, z]))
    return None if rows is None else read_only(rows)


def _candidate_planes(
    epoch: Epoch, ring: np.ndarray | None, view: np.ndarray, config: ExtractionConfig
) -> PathResult:
    """The planes of the range image's or the RANSAC loop's candidates of ``epoch`` with
    ``ring`` (N,) (None: RANSAC) seen from ``view`` (3,) m; of a decimated grid when it
    is denser than ``grid_max_columns`` / ``grid_max_rows`` (:mod:`.decimate`), inliers
    as indices of the whole scan."""
    keep = None
    if ring is not None:
        keep = kept_points(ring, epoch.scan.t, config.grid_max_columns, config.grid_max_rows)
    if ring is not None and keep is not None:
        sub_scan, sub_ring = subset_scan(epoch.scan, ring, keep)
        sub = Epoch(sub_scan, epoch.points[keep], epoch.origins, epoch.twist)
        found = _candidate_planes(sub, sub_ring, view, config.model_copy(
            update={"grid_max_columns": None, "grid_max_rows": None}))  # fmt: skip
        return replace(found, inliers=[keep[i] for i in found.inliers])
    seg = reused(epoch, ring, view, config)  # extraction.segmentation_reuse
    if seg is None:
        made = lidar_candidates(epoch.points, config, ring, view, epoch.scan.t)
        seg = remembered(epoch, ring, view, config, *made)
    candidates, sigma, ransac = seg.candidates, seg.sigma, seg.ransac
    fits, n_small = fit_candidates(candidates, epoch.points, config)
    adjust = _agreement(epoch, ring, seg, config, fits) if ransac else None
    planes, inliers, n_rejected = build_planes(
        fits, epoch, sigma, _fit_config(config, ransac), adjust
    )
    return PathResult(planes, inliers, sigma, 0, len(candidates), n_small + n_rejected)


def _agreement(
    epoch: Epoch,
    ring: np.ndarray | None,
    seg: Segmentation,
    config: ExtractionConfig,
    fits: PlaneFits,
) -> Adjust | None:
    """The plane builder's hook that refuses RANSAC fits across other surfaces
    (``ransac_normal_agreement_deg``, :mod:`.agreement`); None when off or without a grid.
    The pixel normals are those of the segmentation's points (a reused one's: of the
    extraction that made it)."""
    if config.ransac_normal_agreement_deg is None or ring is None:
        return None
    found = seg.agreement_normals(
        lambda: point_normals(epoch.points, ring, epoch.scan.t, seg.sigma, config)
    )
    if found is None:
        return None

    def adjust(kept: np.ndarray, normals: np.ndarray, offsets: np.ndarray) -> np.ndarray:
        members = [fits.members(int(g)) for g in kept]
        refused = cutting_planes(normals[kept], members, found, config)
        return kept[~refused]

    return adjust


def _native_planes(
    epoch: Epoch, rows: np.ndarray, view: np.ndarray, config: ExtractionConfig
) -> PathResult | None:
    """The planes of a cloud without ``ring`` but with times, its recovered ``rows`` (N,)
    int64 taken as the ring (module docstring); None without times or planes."""
    if epoch.scan.t is None:
        return None
    # One origin for all rows: recovered rows are not the rig's ring ids.
    origins = None if epoch.origins is None else epoch.origins.mean(axis=0, keepdims=True)
    ringed = Epoch(_ringed(epoch.scan, rows), epoch.points, origins, epoch.twist)
    found = _candidate_planes(ringed, rows, view, config)
    return found if found.planes else None


@identity_memo
def _scan_rows(points: np.ndarray, x: float, y: float, z: float) -> tuple[np.ndarray, str] | None:
    """:func:`.rows.scan_rows` of the raw ``points`` (N, 3) seen from ``(x, y, z)`` m,
    rows read-only and memoised (:mod:`planodom.extraction.memo`): an epoch's
    extractions of one scan (with the predicted twist, then its own) share them."""
    found = scan_rows(points, np.array([x, y, z]))
    return None if found is None else (read_only(found[0]), found[1])


def _ringed(scan: Scan, rows: np.ndarray) -> Scan:
    """``scan`` with its recovered ``rows`` (N,) as the ring; for a plain :class:`Scan`
    the same object for the same arrays (memoised on them), so that what later steps
    memoise on the ring field is computed once per scan (and the copies are made once)."""
    if type(scan) is not Scan:
        return replace(scan, ring=rows)
    return _ringed_fields(scan.points, rows, scan.t, scan.label)


@identity_memo
def _ringed_fields(
    points: np.ndarray, rows: np.ndarray, t: np.ndarray | None, label: np.ndarray | None
) -> Scan:
    """A :class:`Scan` of these fields (memoised, :func:`_ringed`)."""
    return Scan(points, ring=rows, t=t, label=label)


def _fit_config(config: ExtractionConfig, ransac: bool) -> ExtractionConfig:
    """``config`` for the plane builder: ``viewpoint_planes: ransac`` resolved to
    "rejected" for the RANSAC loop's candidates and "kept" for the range image's."""
    if config.viewpoint_planes != "ransac":
        return config
    rule = "rejected" if ransac else "kept"
    return config.model_copy(update={"viewpoint_planes": rule})


def member_fits(candidates: list[np.ndarray], points: np.ndarray, rows: np.ndarray) -> PlaneFits:
    """Plain TLS fits of the candidate inlier sets (indices into ``points`` (N, 3), m,
    three or more each) and the number of distinct ``rows`` (N,) each spans."""
    fits = [tls_fit(points[c]) for c in candidates]
    return _pack(candidates, fits, _rows_spanned(candidates, rows))


def _rows_spanned(candidates: list[np.ndarray], rows: np.ndarray) -> np.ndarray:
    """(C,) int64 the number of distinct ``rows`` (N,) of each candidate (indices): one
    compiled pass (:func:`.grid.distinct_per_block`) for integer rows from 0, else
    ``np.unique`` per candidate."""
    r = np.asarray(rows)
    small = (
        r.dtype.kind in "iu" and len(r) > 0 and 0 <= r.min() and r.max() < max(2**16, 4 * len(r))
    )
    if not candidates or not small:
        return np.array([len(np.unique(r[c])) for c in candidates], dtype=np.int64)
    bounds = np.zeros(len(candidates) + 1, dtype=np.int64)
    np.cumsum([len(c) for c in candidates], out=bounds[1:])
    keys = r.astype(np.int64)[np.concatenate(candidates)]
    return distinct_per_block(keys, bounds, int(r.max()) + 1)


def _pack(
    inliers: list[np.ndarray],
    fits: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
    n_rows: np.ndarray | None,
) -> PlaneFits:
    """:class:`PlaneFits` of (centroid, evals descending, evecs) per inlier set."""
    bounds = np.zeros(len(fits) + 1, dtype=np.int64)
    np.cumsum(np.array([len(i) for i in inliers], dtype=np.int64), out=bounds[1:])
    flat = np.concatenate(inliers) if inliers else np.zeros(0, dtype=np.int64)
    centroid = np.array([c for c, _, _ in fits]).reshape(-1, 3)
    evecs = np.array([v for _, _, v in fits]).reshape(-1, 3, 3)
    return PlaneFits(
        count=np.diff(bounds),
        centroid=centroid,
        offset=-np.einsum("gi,gi->g", evecs[:, :, 2], centroid),
        evals=np.array([e for _, e, _ in fits]).reshape(-1, 3),
        evecs=evecs,
        inliers=flat,
        bounds=bounds,
        outline=np.ones(len(flat), dtype=bool),
        n_rows=n_rows,
    )


def fit_candidates(
    candidates: list[np.ndarray], points: np.ndarray, config: ExtractionConfig
) -> tuple[PlaneFits, int]:
    """Robust TLS fits of the candidate inlier sets (indices into ``points`` (N, 3), m)
    that keep ``min_plane_points`` inliers (all at once, :func:`robust_plane_fits`), and
    the number of the others."""
    big = [c for c in candidates if len(c) >= config.min_plane_points]
    if not big:
        return _pack([], [], None), len(candidates)
    bounds = np.zeros(len(big) + 1, dtype=np.int64)
    np.cumsum([len(c) for c in big], out=bounds[1:])
    flat = np.concatenate(big)
    inlier, ok, centroid, evals, evecs = robust_plane_fits(
        points[flat], bounds, config.inlier_sigma_factor
    )
    count = np.add.reduceat(inlier, bounds[:-1]) if len(flat) else np.zeros(0, np.int64)
    keep = ok & (count >= config.min_plane_points)
    idx = np.flatnonzero(keep)
    # The kept sets' inliers, set after set, by one mask over all of them (not a list of
    # per-set selections concatenated again: ~1 ms an extraction of a 64-beam room);
    # the same arrays as _pack of those lists (tests/extraction/test_lidar_path.py).
    mask = inlier & np.repeat(keep, np.diff(bounds))
    kept_bounds = np.zeros(len(idx) + 1, dtype=np.int64)
    np.cumsum(count[idx], out=kept_bounds[1:])
    evecs, centroid = evecs[idx], centroid[idx]
    fits = PlaneFits(
        count=np.diff(kept_bounds),
        centroid=centroid,
        offset=-np.einsum("gi,gi->g", evecs[:, :, 2], centroid),
        evals=evals[idx],
        evecs=evecs,
        inliers=flat[mask],
        bounds=kept_bounds,
        outline=np.ones(int(kept_bounds[-1]), dtype=bool),
        n_rows=None,
    )
    return fits, len(candidates) - len(idx)
