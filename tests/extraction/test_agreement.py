"""RANSAC planes that cut across other surfaces (planodom.extraction.lidar.agreement):
refused by their inliers' pixel normals; true planes kept (against the scene's truth)."""

from __future__ import annotations

import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction import extract
from planodom.extraction.lidar.agreement import (
    MIN_JUDGED,
    PointNormals,
    _verdicts,
    cutting_planes,
)

from .synth_scans import planes_in_base, rect, scan_lidar


def test_cutting_planes_by_the_share_of_agreeing_pixel_normals():
    """A plane is refused when more than half of its judged inliers' normals are farther
    than the angle from its own; kept with too few judged inliers, or with the rule off."""
    cfg = ExtractionConfig(ransac_normal_agreement_deg=45.0)
    up, side = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    tilted = np.array([np.sin(np.radians(40.0)), 0.0, np.cos(np.radians(40.0))])
    point_normal = np.array([up] * 10 + [side] * 10 + [tilted] * 10)
    has = np.ones(30, dtype=bool)
    has[25:] = False
    found = PointNormals(point_normal, has, np.arange(30))  # a pixel a point
    members = [
        np.arange(0, 10),  # all agree with "up"
        np.arange(10, 20),  # all at 90 deg: a cut across walls
        np.r_[np.arange(0, 4), np.arange(10, 16)],  # 4 agree, 6 do not
        np.r_[np.arange(0, 5), np.arange(10, 15)],  # a tie is not a majority against
        np.arange(20, 25),  # 40 deg: within 45
        np.r_[np.arange(10, 10 + MIN_JUDGED - 1), np.arange(25, 30)],  # too few judged
    ]
    normals = np.tile(up, (len(members), 1))
    refused = cutting_planes(normals, members, found, cfg)
    assert refused.tolist() == [False, True, True, False, False, False]
    off = cutting_planes(
        normals, members, found, ExtractionConfig(ransac_normal_agreement_deg=None)
    )
    assert not off.any()


def test_unjudged_planes_refused_only_when_asked():
    """``ransac_unjudged: refused``: a plane with fewer than MIN_JUDGED inliers that have
    a pixel normal is refused (a level cut whose points lie where the image has no normal:
    facade edges, lone lines; lidar world 161's first scans), one judged and agreeing is
    kept, one judged and disagreeing refused as before; "kept" (default) keeps it."""
    up, side = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    point_normal = np.array([up] * 10 + [side] * 10 + [up] * 10)
    has = np.ones(30, dtype=bool)
    has[20:] = False  # the last ten points have no pixel normal
    found = PointNormals(point_normal, has, np.arange(30))  # a pixel a point
    members = [
        np.arange(0, 10),  # judged, agrees: a level surface
        np.arange(10, 20),  # judged, at 90 deg: a cut the check sees
        np.r_[np.arange(20, 30), np.arange(10, 10 + MIN_JUDGED - 1)],  # unjudged cut
        np.arange(20, 30),  # no inlier judged at all
    ]
    normals = np.tile(up, (len(members), 1))
    on = ExtractionConfig(ransac_normal_agreement_deg=45.0, ransac_unjudged="refused")
    assert cutting_planes(normals, members, found, on).tolist() == [
        False, True, True, True
    ]  # fmt: skip
    default = ExtractionConfig(ransac_normal_agreement_deg=45.0)
    assert default.ransac_unjudged == "kept"
    assert cutting_planes(normals, members, found, default).tolist() == [
        False, True, False, False
    ]  # fmt: skip
    off = on.model_copy(update={"ransac_normal_agreement_deg": None})
    assert not cutting_planes(normals, members, found, off).any()


def _facades(seed: int = 1) -> list:
    """Ground (id 0) and 24 facades 6-16 m wide, 12 m high, 20-70 m away all around,
    turned up to 35 deg from the line of sight."""
    rng = np.random.default_rng(seed)
    scene = [rect([0, 0, 0], [0, 0, 1], up=[1, 0, 0], half_u=120, half_v=120)]
    for k in range(24):
        yaw, dist = np.radians(15.0 * k + rng.uniform(-4, 4)), rng.uniform(20, 70)
        out = np.array([np.cos(yaw), np.sin(yaw), 0.0])
        face = yaw + rng.uniform(-0.6, 0.6)
        normal = -np.array([np.cos(face), np.sin(face), 0.0])
        scene.append(rect(dist * out + [0, 0, 6.0], normal, half_u=rng.uniform(3, 8), half_v=6.0))
    return scene


def test_dense_lidar_at_high_noise_keeps_the_facades_and_drops_the_cuts():
    """A 64-beam scan at 2 cm among 24 facades: without the rule some planes lie tens of
    degrees off every surface they were fitted on (cuts through other facades' scan
    lines); with it none does, and every surface seen by 200 points or more is found."""
    scene = _facades()
    truth = planes_in_base(scene)
    scan = scan_lidar(scene, sigma=0.02, seed=4, n_beams=64, n_azimuth=1024, height=0.8)
    ids, counts = np.unique(scan.label, return_counts=True)
    seen = {int(i) for i, c in zip(ids, counts, strict=True) if c >= 200}

    def off_truth(planes) -> int:
        return sum(abs(p.normal @ truth[p.truth_id][0]) < np.cos(np.radians(20.0)) for p in planes)

    base = ExtractionConfig(range_noise_m=0.02, estimate_noise=False)
    assert base.ransac_normal_agreement_deg == 45.0
    without = extract(scan, base.model_copy(update={"ransac_normal_agreement_deg": None})).planes
    assert off_truth(without) >= 3
    planes = extract(scan, base).planes
    assert off_truth(planes) == 0
    assert seen <= {p.truth_id for p in planes}


def test_point_normals_share_the_range_images_grid_and_first_row_step():
    """The agreement check's pixel normals of a grid the range image declined are the
    range image's own (memoised, :func:`.grid.point_grid`, :func:`.normals.first_row_step`)
    and equal the kernel on a grid filled afresh."""
    from planodom.extraction.lidar.agreement import point_normals
    from planodom.extraction.lidar.grid import fill_grid, grid_indices, point_grid
    from planodom.extraction.lidar.normals import _pixel_normals, first_row_step, pixel_normals
    from planodom.extraction.noise import member_tolerance

    scan = scan_lidar(_facades(), sigma=0.02, seed=3, n_beams=64, n_azimuth=1024, height=1.8)
    cfg = ExtractionConfig(range_noise_m=0.02, estimate_noise=False)
    points = np.ascontiguousarray(scan.points, dtype=np.float64)
    row, col, H, W = grid_indices(scan.ring, scan.t)
    assert col is not None
    P = point_grid(points, row, col, H, W)
    fresh = fill_grid(points.copy(), row * W + col, H * W).reshape(H, W, 3)
    assert point_grid(points, row, col, H, W) is P and not P.flags.writeable
    assert np.array_equal(P, fresh, equal_nan=True)
    tol = member_tolerance(cfg, 0.02)
    pixel_normals(P, 0.02, tol, cfg, np.array([0.0, 0.0, 1.8]))  # the range image's step 1
    shared = first_row_step(P, cfg.region_window, 0.02, tol, cfg.region_normal_sigmas)
    found = point_normals(points, scan.ring, scan.t, 0.02, cfg)
    assert found is not None
    assert first_row_step(P, cfg.region_window, 0.02, tol, cfg.region_normal_sigmas) is shared
    n0, _, ok0 = _pixel_normals(fresh, cfg.region_window, 1, 0.02, tol, cfg.region_normal_sigmas)
    flat = row * W + col
    n, has = found.normals[found.pixel], found.has[found.pixel]
    assert np.array_equal(n, n0.reshape(-1, 3)[flat]) and np.array_equal(has, ok0.reshape(-1)[flat])
    assert has.any()


def test_judged_normals_are_the_all_points_lookup_restricted_to_the_inliers():
    """:meth:`PointNormals.judged` (the normals looked up for a plane's inliers only)
    equals, bit for bit and in order, the earlier lookup of every point's normal (an
    (N, 3) array and an (N,) mask, computed here from a fresh grid) restricted to the
    inliers that have one; so does the verdict of :func:`cutting_planes` on RANSAC sets."""
    from planodom.extraction.lidar.agreement import point_normals
    from planodom.extraction.lidar.grid import fill_grid, grid_indices
    from planodom.extraction.lidar.normals import _pixel_normals
    from planodom.extraction.noise import member_tolerance

    scan = scan_lidar(_facades(2), sigma=0.02, seed=5, n_beams=64, n_azimuth=1024, height=1.8)
    cfg = ExtractionConfig(range_noise_m=0.02, estimate_noise=False)
    points = np.ascontiguousarray(scan.points, dtype=np.float64)
    found = point_normals(points, scan.ring, scan.t, 0.02, cfg)
    assert found is not None
    row, col, H, W = grid_indices(scan.ring, scan.t)
    assert col is not None
    flat = row * W + col
    fresh = fill_grid(points.copy(), flat, H * W).reshape(H, W, 3)
    tol = member_tolerance(cfg, 0.02)
    n0, _, ok0 = _pixel_normals(fresh, cfg.region_window, 1, 0.02, tol, cfg.region_normal_sigmas)
    every_normal, every_has = n0.reshape(-1, 3)[flat], ok0.reshape(-1)[flat]  # the old lookup
    rng = np.random.default_rng(7)
    members = [np.flatnonzero(scan.label == i) for i in np.unique(scan.label)]
    members += [np.sort(rng.choice(len(points), size=k, replace=False)) for k in (1, 50, 4000)]
    members += [rng.permutation(m) for m in members[:3]]  # any order, kept
    for idx in members:
        own = idx[every_has[idx]]
        assert found.judged(idx).tobytes() == every_normal[own].tobytes()
    normals = rng.normal(size=(len(members), 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    for g, idx in enumerate(members[: len(members) // 2]):  # some planes of their own normals
        own = found.judged(idx)
        normals[g] = own[0] if len(own) else normals[g]
    old = PointNormals(every_normal, every_has, np.arange(len(points)))
    got = cutting_planes(normals, members, found, cfg)
    assert got.tolist() == cutting_planes(normals, members, old, cfg).tolist()
    assert 0 < got.sum() < len(got)


def _per_plane(normals, members, found, config):
    """The verdicts by one numpy gather and product per plane (the rule as written)."""
    limit = np.cos(np.radians(config.ransac_normal_agreement_deg))
    out = np.zeros(len(members), dtype=bool)
    for g, idx in enumerate(members):
        own = found.judged(idx)
        if len(own) < MIN_JUDGED:
            out[g] = config.ransac_unjudged == "refused"
            continue
        out[g] = np.count_nonzero(np.abs(own @ normals[g]) >= limit) * 2 < len(own)
    return out


def test_compiled_verdicts_equal_the_per_plane_numpy_products():
    """Random pixel normals around each plane's, some at the limit angle to it (45 deg,
    products within rounding of cos 45: decided by numpy's product), unjudged planes,
    NaN normals: the same verdicts as the per-plane numpy rule, for both unjudged rules."""
    rng = np.random.default_rng(41)
    seen_unsure = False
    for trial in range(40):
        G, M = int(rng.integers(1, 30)), 3000
        normals = rng.normal(size=(G, 3))
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        pix = rng.normal(size=(M, 3))
        pix /= np.linalg.norm(pix, axis=1, keepdims=True)
        members = [
            np.sort(rng.choice(M, int(rng.integers(0, 60)), replace=False)) for _ in range(G)
        ]
        for g, idx in enumerate(members[: G // 2]):  # at the limit: rotate n by 45 deg
            axis = np.cross(normals[g], rng.normal(size=3))
            axis /= np.linalg.norm(axis)
            c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
            at = c * normals[g] + s * np.cross(axis, normals[g])
            pix[idx[: len(idx) // 2]] = at * rng.choice([-1.0, 1.0])
        if trial % 5 == 0:
            pix[rng.integers(0, M, 20)] = np.nan
        has = rng.random(M) < 0.8
        found = PointNormals(pix, has, rng.permutation(M))
        for rule in ("kept", "refused"):
            cfg = ExtractionConfig(ransac_normal_agreement_deg=45.0, ransac_unjudged=rule)
            got = cutting_planes(normals, members, found, cfg)
            np.testing.assert_array_equal(got, _per_plane(normals, members, found, cfg))
        bounds = np.concatenate([[0], np.cumsum([len(m) for m in members])]).astype(np.int64)
        flat = np.concatenate(members).astype(np.int64)
        limit = float(np.cos(np.radians(45.0)))
        _, unsure = _verdicts(pix, has, found.pixel, flat, bounds, normals, limit, False)
        seen_unsure |= bool(unsure.any())
    assert seen_unsure  # the numpy product decided some planes
