"""The TLS plane covariance against a Monte Carlo estimate, and the CPEF weight."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planodom.extraction.deskew import deskew_points
from planodom.extraction.planes.builder import _COS45, orientation_sign
from planodom.extraction.planes.confidence import cpef, mean_incidence
from planodom.extraction.planes.fit import (
    _tls_kernel,
    deskew_jacobian,
    fit_arrays,
    robust_plane_fit,
    robust_plane_fits,
    tls_covariance,
    tls_fit,
)
from planodom.extraction.planes.passes import _orientation_kernel
from planodom.extraction.planes.support import distinct_and_majority
from planodom.geometry import Plane


def _patch(n_pts: int, rng) -> tuple[np.ndarray, np.ndarray, float]:
    """Points on a tilted 4 m x 1.5 m patch 6 m from the origin, its normal and offset."""
    n = np.array([0.6, -0.48, 0.64])
    n /= np.linalg.norm(n)
    e1 = np.cross(n, [0, 0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    c = 6.0 * n + np.array([1.0, 2.0, 0.5]) - (np.array([1.0, 2.0, 0.5]) @ n) * n
    uv = rng.uniform([-2, -0.75], [2, 0.75], (n_pts, 2))
    return c + uv[:, :1] * e1 + uv[:, 1:] * e2, n, float(-n @ c)


def test_covariance_matches_monte_carlo():
    rng = np.random.default_rng(7)
    sigma, n_pts, trials = 0.02, 40, 4000
    pts, n_true, _ = _patch(n_pts, rng)
    noisy = pts[None] + sigma * rng.standard_normal((trials, n_pts, 3))
    c = noisy.mean(axis=1)
    q = noisy - c[:, None]
    vals, vecs = np.linalg.eigh(np.einsum("tni,tnj->tij", q, q))
    normals = vecs[:, :, 0] * np.sign(vecs[:, :, 0] @ n_true)[:, None]
    offsets = -np.einsum("ti,ti->t", normals, c)
    sample = np.cov(np.column_stack([normals, offsets]).T)
    # Predicted from each trial's own fit (sigma estimated from its residuals), averaged.
    pred = np.zeros((4, 4))
    for k in range(0, trials, 20):
        cc, ev, V = tls_fit(noisy[k])
        pred += tls_covariance(ev[None], V[None], cc[None], np.array([n_pts]), 0.0)[0]
    pred /= len(range(0, trials, 20))
    assert np.linalg.norm(pred - sample) / np.linalg.norm(sample) < 0.1
    np.testing.assert_allclose(np.diag(pred), np.diag(sample), rtol=0.12)
    # Rank 3: nothing along the normal.
    assert abs(n_true @ pred[:3, :3] @ n_true) < 1e-3 * np.trace(pred[:3, :3])


def test_covariance_of_a_line_crossed_by_a_short_segment():
    """A long line (30 points, 8 m along x at y = 0) crossed at 90 deg by a 0.46 m,
    10-point segment 3.8 m from it, in z = 0, with noise along the normal of the plane
    (grazing rays: the range noise times |cos| of the incidence): the tilt about the line
    rests on the segment's lever arms, sigma / sqrt(sum (y - mean y)^2) in closed form
    (x and y decouple: the line is centred on x = 0 and the segment sits at x = 0). The
    stated sigma, from each fit's own residuals, matches it; so does the spread of the
    fitted normals (the 2D rig's chance plane of world 32 at 6 mm, epoch 70: stated
    7e-5 rad, rays at 5 deg)."""
    rng = np.random.default_rng(3)
    sigma, trials = 0.006 * np.sin(np.radians(5.0)), 2000
    line = np.column_stack([np.linspace(-4, 4, 30), np.zeros(30), np.zeros(30)])
    seg = np.column_stack([np.zeros(10), 3.8 + np.linspace(-0.23, 0.23, 10), np.zeros(10)])
    pts = np.vstack([line, seg])
    sigma_tilt = sigma / np.sqrt(np.sum((pts[:, 1] - pts[:, 1].mean()) ** 2))
    noisy = np.repeat(pts[None], trials, axis=0)
    noisy[:, :, 2] += sigma * rng.standard_normal((trials, len(pts)))
    tilts, stated = np.empty(trials), np.empty(trials)
    for k in range(trials):
        c, ev, V = tls_fit(noisy[k])
        cov = tls_covariance(ev[None], V[None], c[None], np.array([len(pts)]), 1e-9)[0]
        tilts[k] = V[1, 2] * np.sign(V[2, 2])  # the normal's y: the tilt about the line
        stated[k] = np.sqrt(cov[1, 1])
    assert np.sqrt(np.mean(stated**2)) == pytest.approx(sigma_tilt, rel=0.03)
    assert np.sqrt(np.mean(tilts**2)) == pytest.approx(sigma_tilt, rel=0.05)


def test_covariance_is_floored_for_exact_data():
    rng = np.random.default_rng(1)
    pts, _, _ = _patch(30, rng)
    fit = robust_plane_fit(pts, 3.5)
    n = np.array([len(fit.inliers)])
    cov = tls_covariance(fit.evals[None], fit.evecs[None], fit.centroid[None], n, 1e-4)[0]
    assert np.all(np.isfinite(cov)) and np.linalg.matrix_rank(cov, tol=1e-20) == 3


def test_batched_robust_fits_match_one_at_a_time():
    """The batched robust fit against the per-set one: noisy patches with outliers, exact
    data, a set that falls below three inliers and one that stops early."""
    rng = np.random.default_rng(3)
    sets = []
    for k in range(12):
        pts, n, _ = _patch(int(rng.integers(8, 400)), rng)
        pts = pts + rng.uniform(0.0, 0.03) * rng.standard_normal(pts.shape) * (k % 3 > 0)
        out = rng.random(len(pts)) < 0.2
        pts[out] += rng.uniform(-1.0, 1.0, (int(out.sum()), 1)) * n
        sets.append(pts)
    sets.append(rng.standard_normal((3, 3)))  # three points: an exact plane
    sets.append(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 50], [0, 0, -50.0]]))
    bounds = np.r_[0, np.cumsum([len(s) for s in sets])]
    inlier, ok, c, evals, evecs = robust_plane_fits(np.concatenate(sets), bounds, 3.5)
    for g, pts in enumerate(sets):
        one = robust_plane_fit(pts, 3.5)
        assert ok[g] == (one is not None)
        if one is None:
            continue
        mine = np.flatnonzero(inlier[bounds[g] : bounds[g + 1]])
        np.testing.assert_array_equal(mine, one.inliers)
        np.testing.assert_allclose(c[g], one.centroid, atol=1e-12)
        np.testing.assert_allclose(evals[g], one.evals, rtol=1e-9, atol=1e-12)
        assert abs(abs(evecs[g, :, 2] @ one.normal) - 1.0) < 1e-12
        # the fit returned is the fit of the returned inliers, bit for bit (a converged
        # set keeps its last fit instead of fitting the same inliers again)
        c2, w2, v2 = _tls_kernel(np.ascontiguousarray(pts), mine)
        assert np.array_equal(c[g], c2) and np.array_equal(evals[g], w2)
        assert np.array_equal(evecs[g], v2)


def test_cpef_factors():
    rng = np.random.default_rng(2)
    pts, n, _ = _patch(200, rng)
    inc = mean_incidence(pts, np.zeros(3), n)
    grazing = mean_incidence(pts, pts.mean(axis=0) + 50 * np.cross(n, [0, 0, 1.0]), n)
    # Rows: reference, larger residual, fewer points, thinner, grazing incidence.
    w = cpef(
        np.array([0.006, 0.03, 0.006, 0.006, 0.006]), 0.006, np.array([200, 200, 20, 200, 200]),
        np.array([1.0, 1.0, 1.0, 0.1, 1.0]), np.array([inc, inc, inc, inc, grazing]), 50.0, 1.0,
    )  # fmt: skip
    assert 0 < w[0] <= 1
    assert np.all(w[1:] < w[0])
    # The closed form of the reference row (module docstring of planes.confidence).
    expected = np.exp(-0.25) * (1 - np.exp(-4.0)) * (1 - np.exp(-1.0)) * inc
    assert w[0] == pytest.approx(expected, rel=1e-12)


def test_orientation_sign_faces_the_viewpoint_or_up():
    normals = np.array([[1.0, 0, 0], [1.0, 0, 0], [0, 0, -1.0], [1.0, 0, 0]])
    offsets = np.array([-5.0, -5.0, 0.0, -5.0])  # x = 5, x = 5, z = 0, x = 5
    centroids = np.array([[5.0, 0, 0], [5.0, 0, 0], [3.0, 0, 0], [5.0, 2, 0]])
    views = np.array([[0.0, 0, 1], [9.0, 0, 1], [0.0, 0, 0], [5.0, 0, 1]])
    # Seen from x = 0 (behind the normal) and x = 9 (in front); on the plane: up for the
    # ground, towards the base origin's side of the centroid for a wall.
    s = orientation_sign(normals, offsets, centroids, views)
    np.testing.assert_array_equal(s, [-1.0, 1.0, -1.0, -1.0])
    s = _orientation_kernel(normals, offsets, centroids, views, _COS45)
    np.testing.assert_array_equal(s, [-1.0, 1.0, -1.0, -1.0])


def test_compiled_fit_arrays_match_the_numpy_forms():
    """The builder's one-pass arrays (covariance, widths, RMS, plane tests, scatters,
    orientation) against tls_covariance, too_uncertain, orientation_sign and the scatter
    V diag(l) V^T in numpy (the same operations: equal to the last bits on the machine
    they were written on; allowed to round differently elsewhere), on random fits with
    views near their planes, degenerate fits (zero eigenvalue gaps, 0 or 3 points) and
    strided eigenvector columns as the 2D-rig path passes them."""
    from planodom.config import ExtractionConfig
    from planodom.extraction.planes.builder import too_uncertain

    rng = np.random.default_rng(3)
    G = 500
    evecs = np.linalg.qr(rng.normal(size=(G, 3, 3)))[0][:, :, ::-1]  # strided columns
    evals = np.sort(rng.uniform(0.0, 5.0, size=(G, 3)), axis=1)[:, ::-1]
    evals[:5] = 0.0  # no spread: 0 / 0
    centroids = rng.normal(size=(G, 3)) * 8.0
    count = rng.integers(0, 300, G)
    count[5:8] = [0, 3, 1]
    cfg = ExtractionConfig()
    floor = cfg.covariance_sigma_floor_m
    max_var = float(np.radians(cfg.max_normal_sigma_deg) ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        covs, width, rms, keep, scatter = fit_arrays(
            evals, evecs, centroids, count, floor**2, cfg.min_plane_points,
            cfg.min_plane_width_m, max_var,
        )  # fmt: skip
        ref = tls_covariance(evals, evecs, centroids, count, floor)
        cnt = np.maximum(count, 1).astype(float)
        ref_width = 2.0 * np.sqrt(np.maximum(evals[:, 1], 0.0) / cnt)
        ref_keep = (count >= cfg.min_plane_points) & (ref_width >= cfg.min_plane_width_m)
        ref_keep &= ~too_uncertain(ref, cfg)
    np.testing.assert_allclose(covs, ref, rtol=1e-12, atol=1e-300, equal_nan=True)
    np.testing.assert_allclose(width, ref_width, rtol=1e-15)
    np.testing.assert_allclose(rms, np.sqrt(np.maximum(evals[:, 2], 0.0) / cnt), rtol=1e-15)
    np.testing.assert_array_equal(keep, ref_keep)
    assert 0 < keep.sum() < G
    ref_scatter = np.einsum("gik,gk,gjk->gij", evecs, evals, evecs)
    np.testing.assert_allclose(scatter, ref_scatter, rtol=1e-12, atol=1e-12)
    normals = evecs[:, :, 2]
    offsets = -np.einsum("gi,gi->g", normals, centroids)
    views = centroids + rng.normal(size=(G, 3)) * rng.choice([1e-4, 1.0], size=(G, 1))
    signs = _orientation_kernel(normals, offsets, centroids, views, _COS45)
    np.testing.assert_array_equal(signs, orientation_sign(normals, offsets, centroids, views))


@pytest.mark.parametrize("rate", [1.0, 1e-3, 20.0])
def test_batched_incidences_and_viewpoints_match_per_plane(rate):
    """The one-pass viewpoints and incidences of build_planes against each plane's own
    computation: per-ring origins carried to the reference time with the twist (its
    angular part scaled by ``rate``: the series of the exponential and beyond)."""
    from planodom.extraction.epoch import Epoch
    from planodom.extraction.planes.confidence import mean_incidences
    from planodom.geometry import se3_exp
    from planodom.scan import Scan

    rng = np.random.default_rng(5)
    pts = rng.normal(0, 5, (300, 3))
    ring = rng.integers(0, 4, 300).astype(np.int32)
    t = rng.uniform(-0.05, 0.05, 300)
    origins = rng.normal(0, 1, (4, 3))
    twist = np.array([0.02 * rate, -0.01 * rate, 0.3 * rate, 5.0, 0.2, 0.05])
    epoch = Epoch(Scan(pts, ring, t), pts, origins, twist)
    inliers = rng.permutation(300)[:240].astype(np.int64)
    bounds = np.array([0, 50, 51, 130, 240], dtype=np.int64)
    planes = np.array([0, 2, 3, 1])
    normals = rng.normal(0, 1, (4, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    views = epoch.viewpoints(inliers, bounds, planes, 1.0)
    inc = mean_incidences(pts, inliers, bounds, planes, views, normals)
    for p, g in enumerate(planes):
        idx = inliers[bounds[g] : bounds[g + 1]]
        T = se3_exp(t[idx].mean() * twist)
        view = T[:3, :3] @ origins[ring[idx]].mean(axis=0) + T[:3, 3]
        np.testing.assert_allclose(views[p], view, rtol=0, atol=1e-12)
        rays = pts[idx] - view
        expected = np.mean(np.abs(rays @ normals[p]) / np.linalg.norm(rays, axis=1))
        assert inc[p] == pytest.approx(expected, rel=1e-12)
        assert inc[p] == pytest.approx(mean_incidence(pts[idx], view, normals[p]), rel=1e-12)
    # Without origins: the point above the base origin for every plane.
    bare = Epoch(Scan(pts, ring, t), pts, None, twist)
    np.testing.assert_array_equal(bare.viewpoints(inliers, bounds, planes, 1.5), [[0, 0, 1.5]] * 4)


@pytest.mark.parametrize("big", [False, True])
def test_distinct_rows_and_majority_labels_match_numpy(big):
    """The compiled per-plane ring count and majority label against np.unique on each
    plane's inliers (small ids: the counting branch; ids beyond 2^20: the sorting one),
    with negative labels (unlabelled points) and ties (the smallest label wins)."""
    rng = np.random.default_rng(3)
    shift = (1 << 21) if big else 0
    ring = rng.integers(0, 6, 500) + shift
    labels = np.where(rng.random(500) < 0.2, -1, rng.integers(0, 4, 500) + shift)
    inliers = rng.permutation(500)[:300]
    bounds = np.array([0, 0, 1, 40, 41, 300])
    labels[inliers[40]] = -1  # plane 3: one unlabelled point
    # plane 2: a tie of 19 points each, the smaller label wins
    labels[inliers[1:40]] = np.repeat([shift + 2, shift + 1, -1], [19, 19, 1])
    planes = np.array([4, 2, 1, 3, 0])
    rows, truth = distinct_and_majority(ring, labels, inliers, bounds, planes)
    for p, g in enumerate(planes):
        idx = inliers[bounds[g] : bounds[g + 1]]
        assert rows[p] == len(np.unique(ring[idx]))
        lab = labels[idx][labels[idx] >= 0]
        if len(lab) == 0:
            assert truth[p] == -1
        else:
            values, counts = np.unique(lab, return_counts=True)
            assert truth[p] == values[np.argmax(counts)]
    none_rows, none_truth = distinct_and_majority(None, None, inliers, bounds, planes)
    assert not none_rows.any() and (none_truth == -1).all()


def _wall_seen_over_time(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Points (N, 3) of a tilted wall about 8 m away, swept over 0.1 s (times (N,)): a
    scanner line moving along it, so time and position along the wall are correlated."""
    n = 600
    t = np.sort(rng.uniform(0.0, 0.1, n))
    u = -3.0 + 60.0 * t + rng.normal(0.0, 0.2, n)  # along the wall, with the sweep
    v = rng.uniform(-1.0, 2.0, n)  # up the wall
    e1 = np.array([1.0, 0.2, 0.0]) / np.hypot(1.0, 0.2)
    e2 = np.array([0.0, 0.1, 1.0]) / np.hypot(0.1, 1.0)
    origin = np.array([2.0, 8.0, 0.5])
    return origin + u[:, None] * e1 + v[:, None] * e2, t


@pytest.mark.parametrize("moving", [False, True])
def test_deskew_jacobian_matches_refits_of_points_deskewed_with_another_twist(moving):
    rng = np.random.default_rng(7)
    raw, t = _wall_seen_over_time(rng)
    twist = np.array([0.03, -0.06, 0.3, 4.0, 0.2, 0.05]) * moving
    pts = deskew_points(raw, t, twist)
    c, evals, evecs = tls_fit(pts)
    n = evecs[:, 2]
    J = deskew_jacobian(pts, t, n)
    change = np.zeros((4, 6))
    for k in range(6):
        step = np.zeros(6)
        step[k] = 1e-6
        # independent: deskew again with the perturbed twist and refit
        c2, _, ev2 = tls_fit(deskew_points(raw, t, twist + step))
        n2 = ev2[:, 2] * np.sign(ev2[:, 2] @ n)
        change[:, k] = np.append(n2 - n, -(n2 @ c2) + n @ c) / step[k]
    # exact at a twist of zero; first order in t xi: at 0.3 rad/s and 4 m/s over 0.1 s the
    # exponential's left Jacobian changes it by up to t |w| / 2 and t |v| / 2 |p| (1.5 %)
    scale = np.abs(change).max(axis=1, keepdims=True)
    assert np.all(np.abs(J - change) <= (0.03 if moving else 1e-4) * scale)
    np.testing.assert_allclose(deskew_jacobian(pts, t, n, (c, evals, evecs)), J, atol=1e-12)


def test_planes_carry_the_deskew_jacobian_through_flips_and_transforms():
    rng = np.random.default_rng(8)
    pts, t = _wall_seen_over_time(rng)
    c, _, evecs = tls_fit(pts)
    n = evecs[:, 2]
    J = deskew_jacobian(pts, t, n)
    plane = Plane(n, float(-n @ c), deskew_jacobian=J)
    np.testing.assert_allclose(plane.flipped().deskew_jacobian, deskew_jacobian(pts, t, -n))
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec([0.1, -0.2, 0.7]).as_matrix()
    T[:3, 3] = [3.0, -1.0, 0.4]
    # independent: a perturbation of the points in frame b, seen in frame a, changes the
    # fit in frame a by the fit's derivative there (a rigid map keeps the fit's geometry)
    moved = pts @ T[:3, :3].T + T[:3, 3]
    dxi = np.array([1e-3, -2e-3, 3e-3, 1e-2, -2e-2, 5e-3])
    ours = plane.transformed(T).deskew_jacobian @ dxi
    shifted = pts + t[:, None] * (np.cross(dxi[:3], pts) + dxi[3:])
    c2, _, ev2 = tls_fit(shifted @ T[:3, :3].T + T[:3, 3])
    ca, _, eva = tls_fit(moved)
    na = eva[:, 2] * np.sign(eva[:, 2] @ (T[:3, :3] @ n))
    n2 = ev2[:, 2] * np.sign(ev2[:, 2] @ na)
    np.testing.assert_allclose(
        ours, np.append(n2 - na, -(n2 @ c2) + na @ ca), atol=2e-3 * np.abs(ours).max()
    )


def test_planes_carry_a_deskew_jacobian_only_when_asked():
    """extraction.deskew_jacobian (switched on by the smoothing mode that reads it) gives
    every plane of a time-spread scan its (4, 6) Jacobian; off, no plane pays for one."""
    from planodom.config import ExtractionConfig
    from planodom.extraction import extract
    from planodom.simulation import simulate_named

    run = simulate_named(
        "paper-loop", "isoclinal", noise=0.006, seed=3, n_epochs=2, motion="continuous"
    )
    off = extract(run.scans[1], ExtractionConfig(range_noise_m=0.006)).planes
    on = extract(run.scans[1], ExtractionConfig(range_noise_m=0.006, deskew_jacobian=True)).planes
    assert len(off) >= 3 and all(p.deskew_jacobian is None for p in off)
    assert len(on) == len(off)
    for p in on:
        assert p.deskew_jacobian is not None and p.deskew_jacobian.shape == (4, 6)
        assert np.all(np.isfinite(p.deskew_jacobian)) and np.any(p.deskew_jacobian != 0)


def test_batched_support_polygons_equal_each_planes_own():
    """support_polygons over the kept planes of a fit set equals support_polygon of each
    plane's outline points (gathered in numpy), degenerate ones (under three outline
    points, collinear) included."""
    from planodom.extraction.planes.support import support_polygon, support_polygons

    rng = np.random.default_rng(8)
    G, N = 6, 400
    points = rng.normal(size=(N, 3)) * 3.0
    points[50:60] = np.linspace(0, 1, 10)[:, None] * np.array([1.0, 2.0, 0.5])  # a line
    inliers = np.concatenate(
        [rng.permutation(N)[:k] for k in (40, 2, 0, 90, 30)] + [np.arange(50, 60)]
    )
    sizes = [40, 2, 0, 90, 30, 10]
    bounds = np.r_[0, np.cumsum(sizes)]
    outline = rng.uniform(size=len(inliers)) < 0.7
    outline[bounds[5] : bounds[6]] = True
    evecs = np.linalg.qr(rng.normal(size=(G, 3, 3)))[0]
    centroids = rng.normal(size=(G, 3))
    kept = np.array([5, 0, 1, 3, 2, 4])
    got = support_polygons(points, inliers, bounds, outline, kept, centroids, evecs)
    for poly, g in zip(got, kept, strict=True):
        idx = inliers[bounds[g] : bounds[g + 1]]
        own = support_polygon(
            points[idx[outline[bounds[g] : bounds[g + 1]]]], centroids[g], evecs[g][:, :2]
        )
        np.testing.assert_array_equal(poly, own)
    assert len(got[0]) == len(got[2]) == len(got[4]) == 0  # a line, 2 points, none
    assert all(len(p) >= 3 for p in (got[1], got[3], got[5]))
