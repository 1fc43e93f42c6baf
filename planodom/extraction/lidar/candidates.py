"""Planes of a dense 3D scan (a spinning lidar, or points without rings).

1. The cloud is reduced to one point per ``voxel_size_m`` voxel (open3d's voxel grid,
   which is deterministic, in its own order).
2. A RANSAC plane search (:func:`.ransac.segment_plane`: three-point
   samples, at most ``ransac_iterations``, early stop at ``ransac_probability``) runs in a
   loop on the voxel points not yet explained, its samples drawn from one
   ``np.random.default_rng(config.seed)`` per scan, so that a scan gives the same planes
   every time, in every process. Not open3d's ``segment_plane``: it is not reproducible
   across processes, or even between two calls, despite ``o3d.utility.random.seed``
   (isl-org/Open3D#7270).
3. The inliers of each RANSAC plane are split into connected clusters as seen from the
   viewpoint (occupancy grid of ``cluster_gap_deg`` cells in azimuth and elevation,
   8-connected, wrapping in azimuth), so that two coplanar but separate walls become two
   planes while the rings of one ground plane, which spread apart with range, stay one.
4. Each cluster is refit by total least squares, twice on the full-resolution points
   within the distance tolerance of it and inside its (dilated) cells and not taken by an
   earlier plane; these points are the candidate inlier set (the caller refits it
   robustly). Voxel points that the refit plane explains are not searched again.

Steps 2 to 4 run compiled (numba, :func:`_ransac_loop`), one call per scan, the samples
included: numpy's ``Generator.integers`` draws, made bit for bit from the seed's PCG64
outputs (:func:`.ransac.draw_stream`). Sparse lidars give many small planes and clusters,
and the dozen numpy and numba calls per plane, then a draw and a call per plane, cost
more than their work (an indoor 16-beam scan at 2 cm: ~18 planes, ~40 clusters).

With rings (and ``range_image``) the candidates come from region growing on the range
image instead (:mod:`.rangeimage`); the loop above is its fallback.

The distance tolerance is ``max(member_sigma_factor * sigma, tolerance_floor_m)`` with
sigma from :func:`planodom.extraction.noise.effective_noise`: the configured range noise,
or the noise measured along the rings (second differences, :func:`ring_noise`) when
larger.
"""

from __future__ import annotations

import numba
import numpy as np

from planodom._open3d import o3d
from planodom.config import ExtractionConfig
from planodom.extraction.kernels import add_outer
from planodom.extraction.lidar.cells import cell_index, cell_members
from planodom.extraction.lidar.clusters import cell_buckets, cluster_cells
from planodom.extraction.lidar.grid import plane_members, ring_layout
from planodom.extraction.lidar.rangeimage import range_image_candidates
from planodom.extraction.lidar.ransac import draw_stream, log_fail, seed_stream, segment_drawn
from planodom.extraction.noise import effective_noise, member_tolerance
from planodom.median import median


def ring_noise(points: np.ndarray, ring: np.ndarray | None, config: ExtractionConfig) -> float:
    """Noise (m) measured along the rings by second differences; 0 without rings.

    The median of ``|(p[i-1] - 2 p[i] + p[i+1]) x d| / |d|``, ``d = p[i+2] - p[i-2]``
    (the second difference across the line, of standard deviation ``sqrt(6) sigma``), over
    the points (N, 3) sorted by ring in scan order whose four neighbours lie in their run,
    divided by ``0.6745 sqrt(6)``; runs are cut where the ring changes or consecutive
    points are farther apart than ``max(min_gap_m, gap_range_ratio * range)`` (sweeps need
    not be separated for the noise estimate). Corners and gaps are a small minority and do
    not move the median.
    """
    if ring is None or not config.estimate_noise or len(points) < 15:
        return 0.0
    row, _, order = ring_layout(ring)  # memoised: the scan's ring alone
    return ring_noise_in_order(points, order, row, config)


def ring_noise_in_order(
    points: np.ndarray, order: np.ndarray, row: np.ndarray, config: ExtractionConfig
) -> float:
    """:func:`ring_noise` of the points (N, 3) visited in ``order`` (N,) int64, the
    rings' scan order, with ``row`` (N,) int64 the ring of each point (only its equality
    between points counts): ``ring_noise(points[order], row[order], config)`` bit for bit
    (the same terms in the same order), without the sorted copies."""
    if not config.estimate_noise or len(points) < 15:
        return 0.0
    across = _ring_noise_terms(
        np.ascontiguousarray(points, dtype=np.float64),
        np.ascontiguousarray(order, dtype=np.int64),
        np.ascontiguousarray(row, dtype=np.int64),
        float(config.min_gap_m),
        float(config.gap_range_ratio),
    )
    if len(across) < 10:
        return 0.0
    return float(median(across) / (0.6745 * np.sqrt(6.0)))


@numba.njit(cache=True)
def _ring_noise_terms(points, order, row, min_gap, gap_ratio):  # pragma: no cover - compiled
    """(K,) metres: the across-line second differences that :func:`ring_noise` takes the
    median of: ``|(p[i-1] - 2 p[i] + p[i+1]) x d| / |d|``,
    ``d = p[i+2] - p[i-2]``, at every point whose four neighbours lie in its run
    (``d != 0``).

    ``points`` (N, 3) are visited in ring ``order`` (N,) (``row`` (N,): the ring of each
    point) in one compiled pass (numba), because numpy needs a sorted copy of the points
    and ~15 array passes with temporaries for the run breaks and the cross products.
    """
    m = order.shape[0]
    run = np.empty(m, dtype=np.int64)  # run id of every sorted point
    run[0] = 0
    for j in range(1, m):
        a, b = order[j - 1], order[j]
        d0 = points[b, 0] - points[a, 0]
        d1 = points[b, 1] - points[a, 1]
        d2 = points[b, 2] - points[a, 2]
        step = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        p0, p1, p2 = points[b, 0], points[b, 1], points[b, 2]
        rng = np.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
        new = row[a] != row[b] or step > max(min_gap, gap_ratio * rng)
        run[j] = run[j - 1] + 1 if new else run[j - 1]
    out = np.empty(max(m - 4, 0))
    k = 0
    for j in range(2, m - 2):
        if run[j + 2] != run[j - 2]:
            continue
        i0, i1, i2, i3, i4 = order[j - 2], order[j - 1], order[j], order[j + 1], order[j + 2]
        e0 = points[i4, 0] - points[i0, 0]
        e1 = points[i4, 1] - points[i0, 1]
        e2 = points[i4, 2] - points[i0, 2]
        norm = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        if not norm > 0:
            continue
        s0 = points[i1, 0] - 2.0 * points[i2, 0] + points[i3, 0]
        s1 = points[i1, 1] - 2.0 * points[i2, 1] + points[i3, 1]
        s2 = points[i1, 2] - 2.0 * points[i2, 2] + points[i3, 2]
        c0 = s1 * e2 - s2 * e1
        c1 = s2 * e0 - s0 * e2
        c2 = s0 * e1 - s1 * e0
        out[k] = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2) / norm
        k += 1
    return out[:k]


@numba.njit(cache=True)
def _tls_normal(pts, idx):  # pragma: no cover - compiled
    """Centroid (3,) and unit normal (3,) (the scatter's least eigenvector) of the points
    ``pts[idx]``: :func:`planodom.extraction.planes.fit.tls_fit` compiled, equal to it to
    rounding (the sums in another order)."""
    k = idx.shape[0]
    c = np.zeros(3)
    for i in range(k):
        for a in range(3):
            c[a] += pts[idx[i], a]
    c /= k
    s = np.zeros((3, 3))
    for i in range(k):
        add_outer(s, pts[idx[i], 0] - c[0], pts[idx[i], 1] - c[1], pts[idx[i], 2] - c[2])
    s[1, 0], s[2, 0], s[2, 1] = s[0, 1], s[0, 2], s[1, 2]
    _, v = np.linalg.eigh(s)
    return c, np.ascontiguousarray(v[:, 0])


@numba.njit(cache=True)
def _within(pts, idx, c, n, tol):  # pragma: no cover - compiled
    """The indices ``idx`` (in order) of the points ``pts[idx]`` within ``tol`` of the
    plane through ``c`` with normal ``n``."""
    out = np.empty(idx.shape[0], dtype=np.int64)
    k = 0
    for i in range(idx.shape[0]):
        j = idx[i]
        r = (pts[j, 0] - c[0]) * n[0] + (pts[j, 1] - c[1]) * n[1] + (pts[j, 2] - c[2]) * n[2]
        if abs(r) <= tol:
            out[k] = j
            k += 1
    return out[:k]


@numba.njit(cache=True)
def _refit_clusters(  # noqa: PLR0913 - the buckets of one RANSAC plane, flat for numba
    points,
    vox,
    tol,
    min_vox,
    min_points,
    labs,
    mem_idx,
    mem_b,
    pt_idx,
    pt_b,
    vx_idx,
    vx_b,
    remaining,
    taken,
):  # pragma: no cover - compiled
    """Step 4 of the module docstring for the clusters ``labs`` (ascending) of one RANSAC
    plane: each cluster's voxels ``mem_idx[mem_b[l]:mem_b[l + 1]]``, its region's points
    not yet taken ``pt_idx[pt_b[l]:...]`` and its region's voxels ``vx_idx[vx_b[l]:...]``
    (all ascending). Clears ``remaining`` (V,) of the voxels each refit plane explains,
    sets ``taken`` (N,) of the candidates and returns them as ``(indices, bounds)``.

    Compiled (numba): the clusters are many and small on sparse lidars (~40 per scan of
    an indoor 16-beam world), and a dozen numpy calls and two numpy fits per cluster cost
    ~0.1 ms each, most of the fallback's time. The regions are disjoint (one label per
    cell), so that ``taken`` never changes another cluster's region."""
    cand_all = np.empty(pt_idx.shape[0], dtype=np.int64)
    bounds = [0]
    k = 0
    for lab in labs:
        members = mem_idx[mem_b[lab] : mem_b[lab + 1]]
        if members.shape[0] < min_vox:
            continue
        c, n = _tls_normal(vox, members)
        region = pt_idx[pt_b[lab] : pt_b[lab + 1]]
        cand = region[:0]
        for _ in range(2):  # refit on the full-resolution points, then select again
            cand = _within(points, region, c, n, tol)
            if cand.shape[0] < 3:
                break
            c, n = _tls_normal(points, cand)
        # Voxels this plane explains are not searched again.
        for j in _within(vox, vx_idx[vx_b[lab] : vx_b[lab + 1]], c, n, tol):
            remaining[j] = False
        if cand.shape[0] >= min_points:
            for j in cand:
                taken[j] = True
            cand_all[k : k + cand.shape[0]] = cand
            k += cand.shape[0]
            bounds.append(k)
    return cand_all[:k], np.array(bounds)


def lidar_candidates(
    points: np.ndarray,
    config: ExtractionConfig,
    ring: np.ndarray | None = None,
    viewpoint: np.ndarray | None = None,
    t: np.ndarray | None = None,
) -> tuple[list[np.ndarray], float, bool]:
    """Candidate inlier sets (indices into ``points`` (N, 3), metres), the sigma used (m),
    and whether the RANSAC loop found them (else the range image).

    ``viewpoint`` (3,), metres: where the scan was taken from (clusters are separated by
    angular gaps as seen from there); the base origin if None. With ``ring`` (and
    ``config.range_image``) planes are grown on the range image
    (:func:`.rangeimage.range_image_candidates`, ``t`` (N,) s gives the columns); the
    RANSAC loop (:func:`ransac_candidates`) runs when that declines (noisy pixel normals,
    no usable times) or grows no candidate.
    """
    sigma = effective_noise(config, ring_noise(points, ring, config))
    view = np.zeros(3) if viewpoint is None else np.asarray(viewpoint, dtype=np.float64)
    if ring is not None and config.range_image:
        grown = range_image_candidates(points, ring, t, sigma, config, view)
        # a range image that gave no candidate at all is no evidence of no plane: a real
        # cloud's grid can be too sparse for pixel normals (nebula's dual-return VLP-16
        # scan: a third of the pixels filled, none grown in one of five scans, where
        # RANSAC finds 51 planes); RANSAC decides, as for rows that gave no plane
        if grown:
            return grown, sigma, False
    return ransac_candidates(points, config, view, member_tolerance(config, sigma)), sigma, True


def ransac_candidates(
    points: np.ndarray, config: ExtractionConfig, view: np.ndarray, tol: float
) -> list[np.ndarray]:
    """Steps 1 to 4 of the module docstring: candidate inlier sets (indices into
    ``points`` (N, 3), m) of the RANSAC loop, clusters seen from ``view`` (3,), m,
    distance tolerance ``tol`` (m)."""
    n_az = int(np.ceil(360.0 / config.cluster_gap_deg))
    # open3d's voxel grid is deterministic (checked: the same voxels in the same order in
    # separate processes and with 1 or 2 OpenMP threads). Its order (a hash map's) is kept:
    # it scatters the voxels in space, so the same seed does not sample the same places in
    # consecutive, similar scans. Sorted by coordinates it did, and a wrong plane found by
    # chance recurred over several epochs (paper loop, lidar32, sigma = 0: 5 of 40).
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    vox = np.asarray(pcd.voxel_down_sample(config.voxel_size_m).points)
    vox_az, vox_el = cell_index(vox, view, config.cluster_gap_deg, n_az)
    pt_az, pt_el = cell_index(points, view, config.cluster_gap_deg, n_az)
    min_vox = max(3, config.min_plane_points // 4)
    # Our own RANSAC (.ransac), not open3d's segment_plane: that one gives different
    # planes in two processes despite o3d.utility.random.seed and one thread
    # (isl-org/Open3D#7270). One generator per scan: the same scan and seed give the same
    # planes.
    # the points and voxels of each angular cell (ascending)
    n_el = 1 + max(int(pt_el.max(initial=0)), int(vox_el.max(initial=0)))
    vox_cell = cell_members(vox_az, vox_el, n_az, n_el)
    pt_cell = cell_members(pt_az, pt_el, n_az, n_el)
    fail = log_fail(config.ransac_probability)
    # The draws of one np.random.default_rng(config.seed) per scan, made in the compiled
    # loop from that generator's outputs (bit for bit Generator.integers' draws,
    # .ransac.draw_stream): every draw the planes can take, and a margin for Lemire's
    # rejections, at most 2^20 words (8 MB) to begin with; the scan again with a stream
    # twice as long when it runs out.
    n_words = min((3 * config.max_planes * config.ransac_iterations) // 2 + 1024, 1 << 20)
    while True:
        cand, bounds, done = _ransac_loop(
            points, vox, float(tol), fail, min_vox, int(config.min_plane_points), n_az,
            int(config.max_planes), int(config.ransac_iterations),
            seed_stream(config.seed, n_words), vox_az, vox_el, n_el, *vox_cell, *pt_cell,
        )  # fmt: skip
        if done:
            return [cand[bounds[k] : bounds[k + 1]] for k in range(len(bounds) - 1)]
        n_words *= 2


@numba.njit(cache=True)
def _ransac_loop(  # noqa: PLR0913 - the scan's arrays, flat for numba
    points,
    vox,
    tol,
    fail,
    min_vox,
    min_points,
    n_az,
    max_planes,
    iterations,
    words,
    vox_az,
    vox_el,
    n_el,
    vox_cell,
    vox_cell_b,
    pt_cell,
    pt_cell_b,
):  # pragma: no cover - compiled
    """Steps 2 to 4 of the module docstring: up to ``max_planes`` calls of
    :func:`_ransac_plane`, each with ``iterations`` draws from the generator whose outputs
    are ``words`` (:func:`.ransac.draw_stream`, from its first output on), in one compiled
    call per scan (a Python loop cost ~0.1 ms a plane in draws and calls). Returns the
    candidates (indices, bounds) and False when ``words`` ran out (no result)."""
    remaining = np.ones(vox.shape[0], dtype=np.bool_)
    taken = np.zeros(points.shape[0], dtype=np.bool_)
    state = np.zeros(3, dtype=np.int64)
    out = np.empty(points.shape[0], dtype=np.int64)  # a point joins one candidate at most
    bounds = [0]
    k = 0
    n_rem = vox.shape[0]
    for _ in range(max_planes):
        if n_rem < min_vox:
            break
        samples = draw_stream(words, state, n_rem, iterations)
        if state[2]:
            return out[:0], np.zeros(1, dtype=np.int64), False
        n_rem, cand, cb = _ransac_plane(
            points, vox, tol, fail, min_vox, min_points, n_az, samples, vox_az, vox_el,
            n_el, remaining, taken, vox_cell, vox_cell_b, pt_cell, pt_cell_b,
        )  # fmt: skip
        if n_rem < 0:
            break
        if k + cand.shape[0] > out.shape[0]:  # not expected: taken points join no other
            grown = np.empty(2 * (k + cand.shape[0]), dtype=np.int64)
            grown[:k] = out[:k]
            out = grown
        out[k : k + cand.shape[0]] = cand
        for j in range(1, cb.shape[0]):
            bounds.append(k + cb[j])
        k += cand.shape[0]
    return out[:k], np.array(bounds), True


@numba.njit(cache=True)
def _ransac_plane(  # noqa: PLR0913 - one RANSAC plane's step, flat for numba
    points,
    vox,
    tol,
    fail,
    min_vox,
    min_points,
    n_az,
    samples,
    vox_az,
    vox_el,
    n_el,
    remaining,
    taken,
    vox_cell,
    vox_cell_b,
    pt_cell,
    pt_cell_b,
):  # pragma: no cover - compiled
    """Steps 2 to 4 of the module docstring for one RANSAC plane of the voxels
    ``vox`` (V, 3) still ``remaining`` (V,), with the raw draws ``samples`` (T, 3) of
    :func:`.ransac.draw_samples`: ``(n_remaining, indices, bounds)``, the candidates as
    :func:`_refit_clusters` returns them and the number of voxels left (-1: the loop
    ends). Updates ``remaining`` and ``taken`` (N,). Compiled, one call per plane: the
    dozen numpy and numba calls per plane it replaces cost more than their work on the
    small scans of sparse indoor lidars; the same steps in the same order, so the same
    candidates bit for bit."""
    none = np.zeros(0, dtype=np.int64)
    rem = np.flatnonzero(remaining)
    xyz = np.empty((3, rem.shape[0]))
    for i in range(rem.shape[0]):
        for a in range(3):
            xyz[a, i] = vox[rem[i], a]
    _, local = segment_drawn(xyz, samples, tol, fail)
    inl = rem[local]
    if inl.shape[0] < min_vox:
        return -1, none, np.zeros(1, dtype=np.int64)
    for _ in range(2):  # RANSAC's plane is rough: refit it, select again
        c, n = _tls_normal(vox, inl)
        inl = _within(vox, rem, c, n, tol)
        if inl.shape[0] < min_vox:
            break
    if inl.shape[0] < min_vox:
        for j in rem:
            remaining[j] = False
        return -1, none, np.zeros(1, dtype=np.int64)
    for j in inl:
        remaining[j] = False
    labels, window, lo = cluster_cells(vox_az[inl], vox_el[inl], n_az)
    n_lab = window.max() + 1
    # The (dilated) cluster of every point and voxel (-1: none). The regions of the
    # clusters are disjoint (one label per cell), so that `taken`, updated cluster by
    # cluster in _refit_clusters, never changes another cluster's region: they are
    # grouped once, over the points not yet taken (each group ascending).
    pt_idx, pt_b = cell_buckets(pt_cell, pt_cell_b, n_el, taken, window, lo, n_lab)
    # only the voxels still remaining: the others have nothing left to clear
    vx_idx, vx_b = cell_buckets(vox_cell, vox_cell_b, n_el, ~remaining, window, lo, n_lab)
    pos, mem_b = plane_members(labels, n_lab)  # labels in [1, n_lab): all kept
    mem_idx = inl[pos]
    cand, bounds = _refit_clusters(
        points, vox, tol, min_vox, min_points, np.unique(labels),
        mem_idx, mem_b, pt_idx, pt_b, vx_idx, vx_b, remaining, taken,
    )  # fmt: skip
    return np.count_nonzero(remaining), cand, bounds
