"""The one plane builder of both paths: from TLS fits to oriented planes.

Both paths end in TLS fits of candidate inlier sets (:class:`PlaneFits`): the 2D-rig
path's group refits (:mod:`planodom.extraction.rig2d.groupfit`), the lidar path's robust
fits of its candidates (:func:`.fit.robust_plane_fits`). :func:`build_planes` then, for all
fits at once:

1. rejects fits with fewer than ``min_plane_points`` inliers, thinner than
   ``min_plane_width_m`` (``2 sqrt(l2 / N)``) or whose normal is known only to worse than
   ``max_normal_sigma_deg`` (``sqrt(trace Cov(n))`` of the covariance, :mod:`.fit`);
2. orients the normals to the side the sensor saw the plane from (:func:`orientation_sign`,
   viewpoints from :class:`planodom.extraction.epoch.Epoch`);
3. weights them by CPEF (:mod:`.confidence`);
4. lets the caller adjust the kept planes (the 2D rig's time windows keep one plane per
   wall, :mod:`planodom.extraction.rig2d.windows`);
5. gives each its support polygon (:mod:`.support`) and majority true label, and, when
   the scan has times and ``extraction.deskew_jacobian`` asks, the fit's first-order
   change with the deskewing twist (:func:`.fit.deskew_jacobian`, times divided by the
   epoch's span ``max |t|``: the smoothing scales it by the change of motion over an
   epoch).

Viewpoints: with sensor origins a plane is seen from the mean origin of the scanners that
saw its inliers (carried to the reference time with the twist at their mean time);
without, from ``(0, 0, viewpoint_height_m)`` in the base frame: a point above the base
origin, so that a ground plane through the base origin (a vehicle frame on the ground,
rig.yaml absent) still gets its normal up, and walls, whose distance from that point
equals their distance from the origin, face the vehicle.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction.epoch import Epoch
from planodom.extraction.planes.assembly import kept_set, made, unit_rows
from planodom.extraction.planes.confidence import cpef
from planodom.extraction.planes.fit import deskew_jacobian
from planodom.extraction.planes.passes import fits_views_signs, rows_labels_polygons, view_mode
from planodom.geometry import Plane, PlaneSupport
from planodom.planes import hand_over

#: ``adjust(kept, normals, offsets) -> kept``: may change the oriented (G, 3) normals and
#: (G,) offsets of the kept planes in place and drop planes (step 4).
Adjust = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]
#: cos 45 deg: a plane through its viewpoint this close to horizontal gets its normal up.
_COS45 = float(np.cos(np.radians(45.0)))


@dataclass(frozen=True, eq=False)
class PlaneFits:
    """TLS fits of G candidate planes, the input of :func:`build_planes`.

    Attributes:
        count: (G,) int64 inliers. centroid: (G, 3) metres. offset: (G,) d of the
            unoriented normal, metres.
        evals: (G, 3) scatter eigenvalues, descending, m^2.
        evecs: (G, 3, 3) eigenvectors, columns e1, e2, n.
        inliers: (K,) int64 scan indices of all inliers, plane by plane: plane g holds
            ``inliers[bounds[g]:bounds[g + 1]]``. bounds: (G + 1,) int64.
        outline: (K,) bool, the inliers the support polygon is built from (all of them,
            or only those that can be extreme, e.g. the ends of straight runs).
        incidence: (G,) CPEF ``w_incidence`` seen from ``(0, 0, viewpoint_height_m)``
            when the path computed it, or None (computed here from the viewpoints).
        n_rows: (G,) int64 distinct scan lines among each fit's inliers when the path
            knows them (recovered rows), or None (counted here from the scan's ``ring``
            when it has one, else 0: unknown).
    """

    count: np.ndarray
    centroid: np.ndarray
    offset: np.ndarray
    evals: np.ndarray
    evecs: np.ndarray
    inliers: np.ndarray
    bounds: np.ndarray
    outline: np.ndarray
    incidence: np.ndarray | None = None
    n_rows: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.count)

    def members(self, g: int) -> np.ndarray:
        """(K_g,) scan indices of plane g's inliers."""
        return self.inliers[self.bounds[g] : self.bounds[g + 1]]


def too_uncertain(cov: np.ndarray, config: ExtractionConfig) -> np.ndarray:
    """True where a (..., 4, 4) (n, d) covariance puts the normal's 1-sigma error above
    ``config.max_normal_sigma_deg`` (a bool array of the leading shape)."""
    var_n = np.trace(cov[..., :3, :3], axis1=-2, axis2=-1)
    return var_n > np.radians(config.max_normal_sigma_deg) ** 2


def orientation_sign(
    normals: np.ndarray, offsets: np.ndarray, centroids: np.ndarray, viewpoints: np.ndarray
) -> np.ndarray:
    """(G,) +1 or -1: the signs that make the normals point towards the viewpoints.

    Planes ``normals`` (G, 3), ``offsets`` (G,), ``centroids`` (G, 3) (m) are oriented so
    that ``viewpoints`` (G, 3) (or (3,) for all, m) lie on their positive side. If a
    viewpoint lies on its plane (|distance| < 1 mm) a near-horizontal plane
    (|n_z| >= cos 45 deg) gets its normal up, any other its normal towards the base
    origin's side of the centroid.
    """
    views = np.broadcast_to(viewpoints, normals.shape)
    dist = np.einsum("gi,gi->g", normals, views) + offsets
    up = np.where(normals[:, 2] > 0, 1.0, -1.0)
    towards = -np.einsum("gi,gi->g", normals[:, :2], centroids[:, :2])
    side = np.where(towards < 0, -1.0, 1.0)
    on_plane = np.where(np.abs(normals[:, 2]) >= _COS45, up, side)
    return np.where(np.abs(dist) >= 1e-3, np.where(dist > 0, 1.0, -1.0), on_plane)


def through_viewpoint(
    fits: PlaneFits,
    scatter: np.ndarray,
    kept: np.ndarray,
    views: np.ndarray,
    sigma_m: float,
    config: ExtractionConfig,
) -> np.ndarray:
    """(K,) whether the inliers of fits ``kept`` (K,) are as flat about a plane through
    their viewpoint ``views`` (K, 3) as a plane must be about its own (RMS within
    ``member_sigma_factor`` times the noise ``sigma_m``): then the set cannot be told from
    the lidar's own beams (the points of one scan line lie on its laser's cone through
    the viewpoint, range noise moving them along their rays, within it; near-level lines
    across facades at several depths fit a thin, level "plane" fixed to the sensor), and a
    surface through the viewpoint is one the sensor sees edge-on. From the scatter about
    the viewpoint, ``S + N (c - o)(c - o)^T`` (parallel axes)."""
    N = fits.count[kept].astype(np.float64)
    dc = fits.centroid[kept] - views
    S_o = scatter[kept] + N[:, None, None] * dc[:, :, None] * dc[:, None, :]
    rms2 = np.linalg.eigvalsh(S_o)[:, 0] / N
    sigma = max(sigma_m, config.covariance_sigma_floor_m)
    return rms2 <= (config.member_sigma_factor * sigma) ** 2


def time_moments(points: np.ndarray, t: np.ndarray, centroid: np.ndarray) -> np.ndarray:
    """(5, 4, 4) ``sum_i t_i^k h_i h_i^T``, k = 0..4, ``h_i = (p_i - centroid, 1)``, of
    points (M, 3) m seen at times ``t`` (M,) s (``PlaneSupport.time_moments``)."""
    h = np.empty((len(points), 4))
    h[:, :3] = points - centroid
    h[:, 3] = 1.0
    powers = np.asarray(t, dtype=np.float64)[None, :] ** np.arange(5)[:, None]  # (5, M)
    return np.einsum("km,mi,mj->kij", powers, h, h)


def _moments_of(
    epoch: Epoch, config: ExtractionConfig, idx: np.ndarray, centroid: np.ndarray
) -> np.ndarray | None:
    """The time moments of the points ``idx`` (``extraction.time_moments``), or None."""
    t = epoch.scan.t
    return (
        time_moments(epoch.points[idx], t[idx], centroid)
        if config.time_moments and t is not None
        else None
    )


def _plane(fields: dict, unit: bool, normal: np.ndarray, offset: float) -> Plane:
    """The plane of ``fields``: made as it is when ``unit`` (its normal and offset checked
    and scaled, :func:`.assembly.unit_rows`), else by the constructor from the unscaled
    ``normal`` and ``offset``, which checks and raises as it always did."""
    if unit:
        return made(Plane, fields)
    return Plane(**{**fields, "normal": normal, "offset": offset})


def build_planes(
    fits: PlaneFits,
    epoch: Epoch,
    sigma_m: float,
    config: ExtractionConfig,
    adjust: Adjust | None = None,
    narrow: np.ndarray | None = None,
) -> tuple[list[Plane], list[np.ndarray], int]:
    """Planes of the fits that pass the tests (module docstring), in fit order;
    ``narrow`` (G,) bool: :attr:`Plane.narrow` of each fit (None: all False).

    Returns the planes, their inliers ((K,) int64 scan indices each) and the number of
    fits rejected (by the tests or by ``adjust``).
    """
    G = len(fits)
    if G == 0:
        return [], [], 0
    floor = config.covariance_sigma_floor_m
    # the plane tests, viewpoints, incidences and orientation in one compiled call
    max_var_n = float(np.radians(config.max_normal_sigma_deg) ** 2)
    inl = fits.inliers.astype(np.int64, copy=False)
    points = np.ascontiguousarray(epoch.points, dtype=np.float64)
    mode, org, ring_v, t_v, xi = view_mode(epoch)
    covs, width, rms, kept, scatter, views, incidence, n_or, d_or = fits_views_signs(
        fits.evals, fits.evecs, fits.centroid, fits.count, fits.offset, floor**2,
        config.min_plane_points, config.min_plane_width_m, max_var_n, points, inl,
        fits.bounds.astype(np.int64, copy=False),
        np.ones(G) if fits.incidence is None else fits.incidence,
        fits.incidence is None or epoch.origins is not None, mode,
        float(config.viewpoint_height_m), org, ring_v, t_v, xi, _COS45,
    )  # fmt: skip
    if config.viewpoint_planes == "rejected" and len(kept):
        kept = kept[~through_viewpoint(fits, scatter, kept, views[kept], sigma_m, config)]
    conf = cpef(
        rms, max(sigma_m, floor), fits.count, width, incidence,
        config.confidence_points_ref, config.confidence_width_ref_m,
    )  # fmt: skip
    if adjust is not None and len(kept):
        kept = adjust(kept, n_or, d_or)
    planes, inliers = [], []
    rows, truth, polygons = rows_labels_polygons(
        epoch, points, inl, fits.bounds.astype(np.int64, copy=False), fits.outline,
        kept.astype(np.int64, copy=False), fits.centroid, fits.evecs, fits.n_rows is None,
    )  # fmt: skip
    t = epoch.scan.t if config.deskew_jacobian else None
    span = 0.0 if t is None or len(t) == 0 else float(np.max(np.abs(t)))
    # per plane, Python scalars and rows taken once for all (numpy's scalar access per
    # item costs more than the items)
    timed = config.time_moments and epoch.scan.t is not None
    n_rows_all = (rows if fits.n_rows is None else fits.n_rows[kept]).tolist()
    count, offset, confidence = fits.count.tolist(), d_or.tolist(), conf.tolist()
    starts, truths = fits.bounds.tolist(), truth.tolist()
    # every plane's checks and scaling at once (.assembly): then no constructor runs
    kept_i = kept.astype(np.int64, copy=False)
    unit, unit_n, unit_d = unit_rows(n_or, d_or, conf, kept_i)
    unit_offset = unit_d.tolist()
    for k, g in enumerate(kept.tolist()):
        idx = fits.inliers[starts[g] : starts[g + 1]]
        dsk = None
        if t is not None and span > 0.0:
            fit = (fits.centroid[g], fits.evals[g], fits.evecs[g])
            dsk = deskew_jacobian(epoch.points[idx], t[idx] / span, n_or[g], fit)
        centroid = fits.centroid[g]
        moments = _moments_of(epoch, config, idx, centroid) if timed else None
        support = made(PlaneSupport, {
            "centroid": centroid.copy(), "polygon": polygons[k], "n_points": count[g],
            "scatter": scatter[g], "n_rows": int(n_rows_all[k]), "time_moments": moments,
        })  # fmt: skip
        fields = {
            "normal": unit_n[k], "offset": unit_offset[k], "covariance": covs[g],
            "confidence": confidence[g], "support": support, "truth_id": int(truths[k]),
            "deskew_jacobian": dsk, "narrow": narrow is not None and bool(narrow[g]),
        }  # fmt: skip
        planes.append(_plane(fields, unit, n_or[g], offset[g]))
        inliers.append(idx)
    if unit and planes:
        hand_over(planes, kept_set(unit_n, unit_d, conf, covs, fits.centroid, polygons,
                                   narrow, kept_i))  # fmt: skip
    return planes, inliers, G - len(kept)
