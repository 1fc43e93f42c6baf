"""One epoch's points to oriented planes with covariance, confidence and support.

``extract(scan, config, twist, sensor_origins) -> ExtractionResult`` runs:

1. input checks (finite points, times, twist, origins; fewer than 3 points: no planes);
2. deskewing with the twist, when given and the scan has times (:mod:`.deskew`);
3. the path for the scan (:func:`choose_mode`): the 2D-rig path
   (:func:`.rig2d.path.rig2d_planes`: scan-line segments, traces, seeds and greedy growth,
   group refits; without a twist on a moving epoch in time windows, :mod:`.rig2d.windows`)
   or the lidar path (:func:`.lidar.path.lidar_planes`: range-image region growing or
   RANSAC, robust fits);
4. both end in the one plane builder (:func:`.planes.builder.build_planes`): plane tests,
   covariance, orientation towards the sensor, CPEF confidence, support and true label;
5. the planes, largest support first.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from planodom.config import ExtractionConfig
from planodom.errors import GeometryError
from planodom.extraction.deskew import check_twist, deskew_points
from planodom.extraction.epoch import Epoch, PathResult
from planodom.extraction.lidar.path import lidar_planes
from planodom.extraction.memo import identity_memo, read_only
from planodom.extraction.planes.builder import PlaneFits, build_planes
from planodom.extraction.planes.fit import tls_fit
from planodom.extraction.rig2d.path import rig2d_planes
from planodom.extraction.scan_prep import compiled_count_rings, points_times_finite
from planodom.geometry import Plane
from planodom.planes import reorder_handed
from planodom.scan import Scan, check_is_scan

#: Largest coordinate (m) accepted; beyond it squares lose all precision.
MAX_COORDINATE_M = 1e6


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


def extract(
    scan: Scan,
    config: ExtractionConfig | None = None,
    twist: np.ndarray | None = None,
    sensor_origins: np.ndarray | None = None,
) -> ExtractionResult:
    """Planes of one epoch, with diagnostics (see :func:`extract_planes`)."""
    config = ExtractionConfig() if config is None else config
    origins = _check_inputs(scan, sensor_origins)
    xi = check_twist(twist)
    if len(scan) < 3:
        return ExtractionResult([], [], "empty", config.range_noise_m, points=scan.points)
    mode = choose_mode(scan, config)
    points = scan.points
    if xi is not None and scan.t is not None:
        if mode == "rig2d":  # shared, read-only (the lidar path writes its points)
            points = _deskewed(points, scan.t, xi.tobytes())
        else:
            points = deskew_points(points, scan.t, xi)
    epoch = Epoch(scan, points, origins, xi)
    found = rig2d_planes(epoch, config) if mode == "rig2d" else lidar_planes(epoch, config)
    return _result(found, mode, points)


@identity_memo
def _deskewed(points: np.ndarray, t: np.ndarray, twist: bytes) -> np.ndarray:
    """(N, 3) ``points`` (N, 3) deskewed with the twist of bytes ``twist`` (6 float64),
    memoised (:mod:`.memo`) for the 2D-rig path: an epoch lost with its tolerances is
    extracted again with the same twist (:func:`planodom.odometry.twist_sigma.widened_if_lost`),
    and the path then reuses its segments (keyed by these points' identity). Read-only:
    shared."""
    return read_only(deskew_points(points, t, np.frombuffer(twist, dtype=np.float64)))


def refit(
    found: ExtractionResult,
    scan: Scan,
    config: ExtractionConfig,
    twist: np.ndarray,
    sensor_origins: np.ndarray | None = None,
) -> ExtractionResult:
    """The planes of ``found`` (an extraction of ``scan``) fit again to their inliers
    deskewed with ``twist`` (6,): no new segmentation, the same inlier sets, each plane
    built as an extraction builds it (plane tests, covariance, orientation, confidence,
    support; :func:`.planes.builder.build_planes`, without a path's adjustment). For a
    twist close to the one ``found`` was extracted with (the twist fit to its own planes,
    :mod:`planodom.extraction.twist_fit`): an extraction again costs its segmentation."""
    origins = _check_inputs(scan, sensor_origins)
    xi = check_twist(twist)
    if not found.inliers or scan.t is None or xi is None:
        return found
    points = deskew_points(scan.points, scan.t, xi)
    sets = [np.asarray(i, dtype=np.int64) for i in found.inliers]
    fits = [tls_fit(points[i]) for i in sets]
    centroid = np.array([f[0] for f in fits])
    evecs = np.array([f[2] for f in fits])
    inliers = np.concatenate(sets)
    plane_fits = PlaneFits(
        count=np.array([len(i) for i in sets], dtype=np.int64),
        centroid=centroid,
        offset=-np.einsum("gi,gi->g", evecs[:, :, 2], centroid),
        evals=np.array([f[1] for f in fits]),
        evecs=evecs,
        inliers=inliers,
        bounds=np.cumsum([0] + [len(i) for i in sets]).astype(np.int64),
        outline=np.ones(len(inliers), dtype=bool),
    )
    epoch = Epoch(scan, points, origins, xi)
    planes, kept, n_rejected = build_planes(plane_fits, epoch, found.sigma_m, config)
    path = PathResult(planes, kept, found.sigma_m, found.n_segments, len(sets), n_rejected)
    return _result(path, found.mode, points)


def _result(found: PathResult, mode: str, points: np.ndarray) -> ExtractionResult:
    """The path's planes, largest support first (stable)."""
    # largest first, ties in path order: Python's sort is stable, as argsort(kind="stable")
    order = sorted(range(len(found.inliers)), key=lambda k: -len(found.inliers[k]))
    reorder_handed(found.planes, order)  # the builder's set of them (planodom.planes)
    return ExtractionResult(
        planes=[found.planes[i] for i in order],
        inliers=[found.inliers[i] for i in order],
        mode=mode,
        sigma_m=found.sigma_m,
        n_segments=found.n_segments,
        n_candidates=found.n_candidates,
        n_rejected=found.n_rejected,
        points=points,
    )


def _check_inputs(scan: Scan, sensor_origins: np.ndarray | None) -> np.ndarray | None:
    """``sensor_origins`` as an (S, 3) float64 array (None stays None) after checking the
    scan's points, times and the origins; raises :class:`GeometryError`."""
    check_is_scan(scan)
    _check_points_times(scan.points, scan.t)
    if sensor_origins is None:
        return None
    if isinstance(sensor_origins, np.ndarray):  # a rig's: memoised by identity
        return _checked_origins(scan.ring, sensor_origins)
    return _check_origins(scan.ring, sensor_origins)


@identity_memo
def _checked_origins(ring: np.ndarray | None, sensor_origins: np.ndarray) -> np.ndarray:
    """:func:`_check_origins` for a scan's ``ring`` and an array of origins, memoised
    (:mod:`.memo`): a scan extracted again is not checked again (its ring's range is a
    pass over the points); the result is a read-only copy."""
    org = _check_origins(ring, sensor_origins)
    return read_only(np.array(org))


@identity_memo
def _check_points_times(pts: np.ndarray, t: np.ndarray | None) -> None:
    """Raises :class:`GeometryError` for non-finite or absurdly large points (N, 3) or
    non-finite times (N,); memoised (:mod:`.memo`): a scan extracted again is not checked
    again. A scan that passes is passed in one compiled pass
    (:func:`.scan_prep.points_times_finite`, the same decision); the numpy checks find
    and word what fails."""
    if points_times_finite(pts, t, MAX_COORDINATE_M):
        return
    numpy_check_points_times(pts, t)


def numpy_check_points_times(pts: np.ndarray, t: np.ndarray | None) -> None:
    """:func:`_check_points_times` in numpy (not memoised): its errors, and the tests'
    reference."""
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
    if t is not None and not np.all(np.isfinite(t)):
        raise GeometryError("scan times t contain NaN or infinite values")


def _check_origins(ring: np.ndarray | None, sensor_origins: object) -> np.ndarray:
    """:func:`_check_inputs` for given origins (``ring``: the scan's)."""
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
    if len(org) > 1 and np.all(org == org[0]):
        org = org[:1]  # one sensor for every ring (a lidar): no ring field needed
    if len(org) > 1:
        if ring is None:
            raise GeometryError("per-ring sensor_origins need the scan's ring field")
        if len(ring) and (ring.min() < 0 or ring.max() >= len(org)):
            raise GeometryError(
                f"ring ids {ring.min()}..{ring.max()} do not index the {len(org)} sensor_origins"
            )
    return org


def choose_mode(scan: Scan, config: ExtractionConfig) -> str:
    """ "rig2d" or "lidar" for this scan under ``config.mode`` (see ExtractionConfig)."""
    if config.mode != "auto":
        if config.mode == "rig2d" and scan.ring is None:
            raise GeometryError("extraction.mode 'rig2d' needs the scan's ring field")
        return config.mode
    if scan.ring is None:
        return "lidar"
    return "rig2d" if count_rings(scan.ring) <= config.max_rig_rings else "lidar"


@identity_memo
def count_rings(ring: np.ndarray) -> int:
    """Number of distinct ring ids in ``ring`` (N,) (a counting pass for small ids:
    compiled, :func:`.scan_prep.compiled_count_rings`, where it applies, else
    :func:`numpy_count_rings`)."""
    n = compiled_count_rings(ring)
    return numpy_count_rings(ring) if n is None else n


def numpy_count_rings(ring: np.ndarray) -> int:
    """:func:`count_rings` in numpy (not memoised): the fallback and the tests' reference."""
    if len(ring) == 0:
        return 0
    lo, hi = int(ring.min()), int(ring.max())
    if lo >= 0 and hi < 1 << 16:
        return int(np.count_nonzero(np.bincount(ring)))
    return len(np.unique(ring))


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
        :mod:`planodom.extraction.planes.fit`), a CPEF confidence in (0, 1]
        (:mod:`planodom.extraction.planes.confidence`), support (centroid, convex polygon in the
        plane, point count) and ``truth_id`` (majority inlier label, -1 without labels).
        Empty input or fewer than 3 points give no planes.

    Raises:
        GeometryError: NaN / infinite / absurdly large coordinates or times, a malformed
            twist or sensor_origins.
        ConfigError: never for a validated config (an unknown mode fails at load).
    """
    return extract(scan, config, twist, sensor_origins).planes
