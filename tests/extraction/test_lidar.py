"""The 3D path (range-image region growing, seeded RANSAC loop): exact planes,
determinism (also across processes), coplanar but separate walls; the compiled kernels
(range image, RANSAC) against numpy / scipy."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from planodom.config import ExtractionConfig
from planodom.extraction import extract
from planodom.extraction.lidar.candidates import (
    lidar_candidates,
    ring_noise,
    ring_noise_in_order,
)
from planodom.extraction.lidar.grid import (
    fill_grid,
    grid_indices,
    near_pairs,
    ring_order,
    ring_rows,
)
from planodom.extraction.lidar.normals import _pixel_normals
from planodom.extraction.lidar.rangeimage import (
    _flat_pieces,
    _grow_pieces,
    range_image_candidates,
)
from planodom.extraction.lidar.ransac import sample_triples, segment_plane

from .synth_scans import default_scene, planes_in_base, rect, scan_lidar

SCENE = default_scene()
TRUTH = planes_in_base(SCENE)


def test_lidar_planes_exact_and_deterministic():
    scan = scan_lidar(SCENE, n_azimuth=512)
    res = extract(scan)
    assert res.mode == "lidar"
    assert {p.truth_id for p in res.planes} == set(TRUTH)
    for p in res.planes:
        n, d = TRUTH[p.truth_id]
        assert np.degrees(np.arccos(np.clip(p.normal @ n, -1, 1))) < 1e-6
        assert abs(p.offset - d) < 1e-6
    again = extract(scan)
    assert [len(i) for i in again.inliers] == [len(i) for i in res.inliers]
    for a, b in zip(res.planes, again.planes, strict=True):
        np.testing.assert_array_equal(a.coefficients, b.coefficients)


def assert_within_five_sigma(planes) -> None:
    """Each plane's normal and offset lie within 5 sigma (its own fit covariance, plus 1 mm
    on the offset) of its true wall."""
    for p in planes:
        n, d = TRUTH[p.truth_id]
        assert np.linalg.norm(np.cross(p.normal, n)) < 5 * np.sqrt(np.trace(p.covariance[:3, :3]))
        assert abs(p.offset - d) < 5 * np.sqrt(p.covariance[3, 3]) + 1e-3


def test_without_rings_is_3d_and_noisy_fit_is_close():
    sigma = 0.02
    scan = scan_lidar(SCENE, sigma=sigma, n_azimuth=512, with_ring=False)
    res = extract(scan, ExtractionConfig(range_noise_m=sigma))
    assert res.mode == "lidar"
    big = [p for p in res.planes if p.support.n_points > 1000]
    assert {p.truth_id for p in big} == set(TRUTH)
    assert_within_five_sigma(big)


def test_coplanar_separate_walls_are_two_planes():
    scene = [
        SCENE[0],
        rect([8, -6, 2], [-1, 0, 0], half_u=3),  # two pieces of the plane x = 8,
        rect([8, 6, 2], [-1, 0, 0], half_u=3),  # 6 m apart
    ]
    res = extract(scan_lidar(scene, n_azimuth=512))
    walls = [p for p in res.planes if p.truth_id in (1, 2)]
    assert sorted(p.truth_id for p in walls) == [1, 2]
    for p in walls:
        assert p.normal[0] < -0.999 and abs(p.offset - 8.0) < 1e-6


def test_range_image_matches_truth_with_noise_and_dropouts():
    """Ringed scans take the range-image path: noisy walls within a sigma-derived bound,
    the same walls as the RANSAC path, also with no-return beams dropped."""
    sigma = 0.006
    scan = scan_lidar(SCENE, sigma=sigma, n_azimuth=1024, seed=3)
    keep = np.random.default_rng(0).random(len(scan)) > 0.05  # 5 % no-returns
    scan = scan.subset(keep)
    cfg = ExtractionConfig(range_noise_m=sigma)
    res = extract(scan, cfg)
    assert res.mode == "lidar"
    big = [p for p in res.planes if p.support.n_points > 500]
    assert {p.truth_id for p in big} == set(TRUTH)
    assert_within_five_sigma(big)
    ransac = extract(scan, ExtractionConfig(range_noise_m=0.02, range_image=False))
    assert {p.truth_id for p in ransac.planes if p.support.n_points > 500} == set(TRUTH)


# The compiled kernels of the range-image path against independent numpy / scipy versions.


def _grid(sigma: float, seed: int, n_beams: int = 16, n_azimuth: int = 256):
    """A noisy ringed scan with 5 % no-returns on its range-image grid: P (H, W, 3)."""
    scan = scan_lidar(SCENE, sigma=sigma, n_beams=n_beams, n_azimuth=n_azimuth, seed=seed)
    scan = scan.subset(np.random.default_rng(seed).random(len(scan)) > 0.05)
    row, col, H, W = grid_indices(scan.ring, scan.t)
    return fill_grid(scan.points, row * W + col, H * W).reshape(H, W, 3)


def _normals_reference(P, K, sigma, tol, ks, S=1):
    """Step 1 of :mod:`planodom.extraction.lidar.rangeimage` with whole-grid numpy shifts
    (column tangent between the rows r +- S)."""
    up, down = np.full_like(P, np.nan), np.full_like(P, np.nan)
    up[:-S], down[S:] = P[S:], P[:-S]
    th = sum(k * (np.roll(P, -k, axis=1) - np.roll(P, k, axis=1)) for k in range(1, K + 1))
    tv = up - down
    n = np.cross(th, tv)
    nn = np.linalg.norm(n, axis=2)
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / nn[:, :, None]
        s2 = 2.0 * sum(k * k for k in range(1, K + 1))
        e = sigma * np.sqrt(s2 / np.sum(th * th, axis=2) + 2.0 / np.sum(tv * tv, axis=2))
        ok = np.isfinite(nn) & (nn > 0) & np.isfinite(e)
        for Q in (np.roll(P, -K, axis=1), np.roll(P, K, axis=1), up, down):
            dq = Q - P
            res = np.abs(np.sum(dq * n, axis=2))
            ok &= ~(res > tol + ks * e * np.linalg.norm(dq, axis=2))
    return n, e, ok


def _pieces_reference(P, n, e, ok, tol, ks, floor, min_gap, ratio, view, min_px, step):
    """Step 2: edge tests in numpy, scipy's connected components, pieces of min_px
    pixels or more numbered by their first pixel; the gap ratio scaled by the angle
    between the rays over ``step`` (0: unscaled)."""
    H, W = ok.shape
    idx = np.arange(H * W).reshape(H, W)
    below = np.vstack([idx[1:], np.full((1, W), -1)])
    Pf, nf, ef, okf = P.reshape(-1, 3), n.reshape(-1, 3), e.ravel(), ok.ravel()
    src, dst = [], []
    for nb in (np.roll(idx, -1, axis=1), below):
        i, j = idx.ravel(), nb.ravel()
        m = j >= 0
        i, j = i[m], j[m]
        m = okf[i] & okf[j]
        i, j = i[m], j[m]
        dp = Pf[j] - Pf[i]
        dist = np.linalg.norm(dp, axis=1)
        cosang = np.abs(np.sum(nf[i] * nf[j], axis=1))
        lim = np.minimum(floor + ks * np.sqrt(ef[i] ** 2 + ef[j] ** 2), np.pi / 2)
        keep = cosang >= np.cos(lim)
        keep &= np.abs(np.sum(nf[i] * dp, axis=1)) <= tol + ks * ef[i] * dist
        keep &= np.abs(np.sum(nf[j] * dp, axis=1)) <= tol + ks * ef[j] * dist
        rng = np.linalg.norm(Pf[i] - view, axis=1)
        scale = np.ones(len(i))
        if step > 0:
            ui = (Pf[i] - view) / rng[:, None]
            uj = (Pf[j] - view) / np.linalg.norm(Pf[j] - view, axis=1)[:, None]
            angle = np.arccos(np.clip(np.sum(ui * uj, axis=1), -1.0, 1.0))
            scale = np.maximum(1.0, angle / step)
        keep &= dist <= np.maximum(min_gap, ratio * rng * scale)
        src.append(i[keep])
        dst.append(j[keep])
    src, dst = np.concatenate(src), np.concatenate(dst)
    graph = coo_matrix((np.ones(len(src)), (src, dst)), shape=(H * W, H * W))
    _, comp = connected_components(graph, directed=False)
    sizes = np.bincount(comp[okf], minlength=comp.max() + 1)
    lab = np.where(okf & (sizes[comp] >= min_px), comp, -1)
    out = np.full(H * W, -1)
    sel = np.flatnonzero(lab >= 0)
    _, first, inv = np.unique(lab[sel], return_index=True, return_inverse=True)
    out[sel] = np.argsort(np.argsort(first))[inv]
    return out


@pytest.mark.parametrize(("sigma", "step"), [(0.0, 0.0), (0.006, 0.0), (0.02, 0.0), (0.006, 0.02)])
def test_region_growing_kernels_match_numpy_and_scipy(sigma, step):
    P = _grid(sigma, seed=int(sigma * 1000))
    K, ks, tol = 3, 3.0, max(3 * sigma, 0.02)
    n, e, ok = _pixel_normals(P, K, 1, max(sigma, 0.002), tol, ks)
    n_ref, e_ref, ok_ref = _normals_reference(P, K, max(sigma, 0.002), tol, ks)
    np.testing.assert_array_equal(ok, ok_ref)
    assert 0.3 * ok.size < np.count_nonzero(ok) < ok.size
    np.testing.assert_allclose(n[ok], n_ref[ok], rtol=0, atol=1e-12)
    np.testing.assert_allclose(e[ok], e_ref[ok], rtol=1e-12)
    # A short gap limit (0.1 m + 3 % of the range) so that the gap test also cuts edges.
    # step > 0: rows 2 deg apart against a 0.02 rad (1.1 deg) step scale it across rows.
    args = (tol, ks, np.radians(2.0), 0.1, 0.03, np.array([0.0, 0.0, 1.8]), 10, step)
    piece, n_pieces = _grow_pieces(P, n, e, ok, *args)
    ref = _pieces_reference(P, n, e, ok, *args)
    assert n_pieces >= 3
    if step > 0:  # the scaled gap joins rows the unscaled one cuts
        assert n_pieces < _grow_pieces(P, n, e, ok, *args[:-1], 0.0)[1]
    np.testing.assert_array_equal(piece, ref)


@pytest.mark.parametrize("gap", ["incidence", "range"])
def test_a_grown_piece_with_a_few_pixels_off_its_plane(gap):
    """A ground piece (z = 0) that took in 10 pixels of a low object 0.3 m high fails the
    RMS test as a whole; with the incidence gap rule on a sparse grid (whose long edges
    let such pixels in) it is trimmed: the piece keeps its ground pixels."""
    H, W = 8, 64
    r, c = np.meshgrid(np.arange(H), np.arange(W), indexing="ij")
    P = np.stack([5.0 + 0.5 * r, 0.1 * c, np.zeros((H, W))], axis=2)
    P[3, 10:20, 2] = 0.3
    piece = np.zeros(H * W, dtype=np.int64)
    out = _flat_pieces(P, piece, 1, 0.006, ExtractionConfig(), trim=gap == "incidence")
    if gap == "range":
        assert out is None
        return
    assert out is not None
    label, cnt, cen, _, vals, vecs = out
    assert cnt.tolist() == [H * W - 10]
    assert np.all(label[3, 10:20] == -1) and np.count_nonzero(label == 0) == H * W - 10
    assert abs(abs(vecs[0, 2, 0]) - 1.0) < 1e-12 and abs(cen[0, 2]) < 1e-12


@pytest.mark.parametrize("S", [2, 3])
def test_pixel_normals_across_rows_farther_apart_match_numpy(S):
    P = _grid(0.02, seed=S, n_beams=32)
    K, ks, tol = 3, 3.0, 0.06
    n, e, ok = _pixel_normals(P, K, S, 0.02, tol, ks)
    n_ref, e_ref, ok_ref = _normals_reference(P, K, 0.02, tol, ks, S)
    np.testing.assert_array_equal(ok, ok_ref)
    assert 0.2 * ok.size < np.count_nonzero(ok) < ok.size
    np.testing.assert_allclose(n[ok], n_ref[ok], rtol=0, atol=1e-12)
    np.testing.assert_allclose(e[ok], e_ref[ok], rtol=1e-12)
    # the predicted error falls with the row step (the column tangent dominates)
    e1 = _pixel_normals(P, K, 1, 0.02, tol, ks)[1]
    assert np.median(e[ok]) < 0.7 * np.median(e1[np.isfinite(e1)])


def test_dense_lidar_at_high_noise_grows_regions_across_rows_farther_apart():
    # 128 beams 0.24 deg apart at 2 cm: normals across neighbouring rows are too noisy
    # (median predicted error above region_max_normal_error_deg), across rows farther
    # apart they are not; the range image grows the true walls, within 5 sigma.
    sigma = 0.02
    scan = scan_lidar(SCENE, sigma=sigma, n_beams=128, n_azimuth=512, seed=5)
    cfg = ExtractionConfig(range_noise_m=sigma, estimate_noise=False)
    row, col, H, W = grid_indices(scan.ring, scan.t)
    P = fill_grid(scan.points, row * W + col, H * W).reshape(H, W, 3)
    e1 = _pixel_normals(P, cfg.region_window, 1, sigma, 0.06, 3.0)[1]
    assert np.degrees(np.median(e1[np.isfinite(e1)])) > cfg.region_max_normal_error_deg
    grown = range_image_candidates(scan.points, scan.ring, scan.t, sigma, cfg, np.zeros(3))
    assert grown is not None
    res = extract(scan, cfg)
    big = [p for p in res.planes if p.support.n_points > 1000]
    assert {p.truth_id for p in big} == set(TRUTH)
    assert len(big) <= len(TRUTH) + 1  # about one plane per wall, not fragments
    assert_within_five_sigma(big)


def _pairs_reference(label, n_pieces, gap_cols):
    """Step 3's pairs from the label grid shifted by every offset (numpy)."""
    H, W = label.shape
    pairs = []
    for dr in (-2, -1, 0, 1, 2):
        shifted = np.full_like(label, -1)
        shifted[max(0, -dr) : H - max(0, dr)] = label[max(0, dr) : H + min(0, dr)]
        for dc in range(0 if dr > 0 else 1, gap_cols + 1, 2 if abs(dr) == 2 else 1):
            other = np.roll(shifted, -dc, axis=1)
            m = (label >= 0) & (other >= 0) & (label != other)
            pairs.append(label[m] * n_pieces + other[m])
    return np.unique(np.concatenate(pairs))


def test_near_pairs_match_shifted_grids():
    rng = np.random.default_rng(0)
    for _ in range(300):
        H, W, C = int(rng.integers(1, 8)), int(rng.integers(1, 40)), int(rng.integers(1, 6))
        label = rng.integers(-1, C, size=(H, (W + 2) // 3))
        if rng.random() < 0.5:  # runs of 3, as pieces are
            label = np.repeat(label, 3, axis=1)
        label = np.ascontiguousarray(label, dtype=np.int64)
        gap = int(rng.integers(1, 2 * label.shape[1] + 2))  # also wider than the grid
        np.testing.assert_array_equal(
            np.unique(near_pairs(label, C, gap)), _pairs_reference(label, C, gap)
        )


def estimate_line_noise(points: np.ndarray, run_start: np.ndarray) -> float:
    """Independent numpy reference of the noise across scan lines: for points
    ``p[i-1], p[i], p[i+1]`` of a straight run the second difference has, across the
    line, standard deviation ``sqrt(6) sigma``; its component across ``p[i+2] - p[i-2]``
    at every point whose four neighbours lie in its run, ``median(|.|) / (0.6745 sqrt(6))``.
    """
    m = len(points)
    if m < 15:
        return 0.0
    run_id = np.cumsum(run_start)
    ok = run_id[4:] == run_id[:-4]
    pm1, p0, pp1 = points[1:-3], points[2:-2], points[3:-1]
    direction = points[4:] - points[:-4]
    norm = np.linalg.norm(direction, axis=1)
    good = ok & (norm > 0)
    if np.count_nonzero(good) < 10:
        return 0.0
    sec = (pm1 - 2.0 * p0 + pp1)[good]
    across = np.linalg.norm(np.cross(sec, direction[good]), axis=1) / norm[good]
    return float(np.median(across) / (0.6745 * np.sqrt(6.0)))


def test_ring_noise_matches_estimate_line_noise():
    """The fused kernel against estimate_line_noise on the stable-sorted rings, with the
    points shuffled and ring ids neither contiguous nor from 0."""
    cfg = ExtractionConfig()
    for seed, sigma in enumerate((0.0, 0.006, 0.05)):
        scan = scan_lidar(SCENE, sigma=sigma, n_azimuth=512, seed=seed)
        perm = np.random.default_rng(seed).permutation(len(scan))
        pts, ring = scan.points[perm], 3 * scan.ring[perm] + 1000
        order = np.argsort(ring, kind="stable")
        row, n_rows = ring_rows(ring)
        np.testing.assert_array_equal(ring_order(row, n_rows), order)
        p, rg = pts[order], ring[order]
        run_start = np.ones(len(p), dtype=bool)
        step = np.linalg.norm(np.diff(p, axis=0), axis=1)
        gap = np.maximum(cfg.min_gap_m, cfg.gap_range_ratio * np.linalg.norm(p[1:], axis=1))
        run_start[1:] = (rg[1:] != rg[:-1]) | (step > gap)
        expected = estimate_line_noise(p, run_start)
        assert ring_noise(pts, ring, cfg) == pytest.approx(expected, rel=1e-12, abs=1e-15)


def test_ring_noise_in_order_matches_the_sorted_copies():
    """The noise of points visited in a given per-ring order (here each ring's azimuth
    order, of shuffled points) against estimate_line_noise on the sorted copies, and bit
    for bit against ring_noise of those copies (the organised path's former call)."""
    cfg = ExtractionConfig()
    for seed, sigma in enumerate((0.0, 0.006, 0.05)):
        scan = scan_lidar(SCENE, sigma=sigma, n_azimuth=512, seed=seed)
        perm = np.random.default_rng(seed).permutation(len(scan))
        pts, ring = scan.points[perm], 3 * scan.ring[perm] + 1000
        order = np.lexsort((np.arctan2(pts[:, 1], pts[:, 0]), ring))
        p, rg = pts[order], ring[order]
        run_start = np.ones(len(p), dtype=bool)
        step = np.linalg.norm(np.diff(p, axis=0), axis=1)
        gap = np.maximum(cfg.min_gap_m, cfg.gap_range_ratio * np.linalg.norm(p[1:], axis=1))
        run_start[1:] = (rg[1:] != rg[:-1]) | (step > gap)
        got = ring_noise_in_order(pts, order, ring, cfg)
        assert got == pytest.approx(estimate_line_noise(p, run_start), rel=1e-12, abs=1e-15)
        assert np.float64(got).tobytes() == np.float64(ring_noise(p, rg, cfg)).tobytes()
    assert ring_noise_in_order(pts[:14], order[:14] % 14, ring[:14], cfg) == 0.0


# The RANSAC fallback (no rings): reproducible across processes, and its kernel against a
# plain numpy RANSAC with the same samples.

_FALLBACK_SCRIPT = """
import hashlib, sys
import numpy as np
sys.path.insert(0, {tests!r})
from synth_scans import default_scene, scan_lidar
from planodom.config import ExtractionConfig
from planodom.extraction import extract
from planodom.extraction.lidar.ransac import segment_plane
scan = scan_lidar(default_scene(), sigma=0.02, n_azimuth=512, seed=5, with_ring=False)
res = extract(scan, ExtractionConfig(range_noise_m=0.02))
raw = segment_plane(scan.points, 0.06, 300, 0.999, np.random.default_rng(0))
h = hashlib.sha256()
for p, idx in zip(res.planes, res.inliers, strict=True):
    h.update(p.coefficients.tobytes())
    h.update(np.asarray(idx, dtype=np.int64).tobytes())
h.update(raw[0].tobytes())
h.update(raw[1].tobytes())
print(len(res.planes), h.hexdigest())
"""


def _digest(res, raw) -> str:
    """The planes and inliers of an extraction, and a raw RANSAC plane and its inliers."""
    h = hashlib.sha256()
    for p, idx in zip(res.planes, res.inliers, strict=True):
        h.update(p.coefficients.tobytes())
        h.update(np.asarray(idx, dtype=np.int64).tobytes())
    h.update(raw[0].tobytes())
    h.update(raw[1].tobytes())
    return f"{len(res.planes)} {h.hexdigest()}"


def test_ransac_fallback_is_reproducible_across_processes():
    """The same scan without rings gives the same planes, bit for bit, in this process
    (twice) and in two fresh interpreters (one and two OpenMP / BLAS threads), and so
    does one raw RANSAC search: open3d's segment_plane did not (isl-org/Open3D#7270;
    open3d 0.20 varies even within one process after the same o3d.utility.random.seed)."""
    scan = scan_lidar(SCENE, sigma=0.02, n_azimuth=512, seed=5, with_ring=False)
    cfg = ExtractionConfig(range_noise_m=0.02)
    res = extract(scan, cfg)
    assert res.mode == "lidar" and len(res.planes) >= len(TRUTH)
    raw = segment_plane(scan.points, 0.06, 300, 0.999, np.random.default_rng(0))
    here = _digest(res, raw)
    raw_again = segment_plane(scan.points, 0.06, 300, 0.999, np.random.default_rng(0))
    assert _digest(extract(scan, cfg), raw_again) == here
    code = _FALLBACK_SCRIPT.format(tests=str(Path(__file__).parent))
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", code],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={
                **os.environ,
                "OMP_NUM_THREADS": str(threads),
                "OPENBLAS_NUM_THREADS": str(threads),
            },
        )
        for threads in (1, 2)
    ]
    outs = [p.communicate(timeout=300) for p in procs]
    for p, (stdout, stderr) in zip(procs, outs, strict=True):
        assert p.returncode == 0, stderr
        assert stdout.strip() == here


def test_ransac_fallback_same_seed_same_candidates_other_seed_same_walls():
    scan = scan_lidar(SCENE, sigma=0.006, n_azimuth=512, seed=2, with_ring=False)
    cfg = ExtractionConfig(range_noise_m=0.006)
    a, sa, _ = lidar_candidates(scan.points, cfg)
    b, sb, _ = lidar_candidates(scan.points, cfg)
    assert sa == sb and len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    other = extract(scan, ExtractionConfig(range_noise_m=0.006, seed=7))
    assert {p.truth_id for p in other.planes if p.support.n_points > 1000} == set(TRUTH)


def _ransac_reference(pts, tol, triples, probability):
    """Plain numpy RANSAC over the given triples: open3d's rules (count, then the sum of
    squared inlier distances; stop after log(1 - p) / log(1 - w^3) hypotheses)."""
    best, best_cnt, best_sse, stop = np.zeros(4), 0, np.inf, len(triples)
    log_fail = np.log1p(-probability) if probability < 1 else -np.inf
    for it, (i, j, k) in enumerate(triples):
        if it >= stop:
            break
        n = np.cross(pts[j] - pts[i], pts[k] - pts[i])
        if not np.linalg.norm(n) > 0:
            continue
        n = n / np.linalg.norm(n)
        r = np.abs(pts @ n - n @ pts[i])
        cnt, sse = np.count_nonzero(r <= tol), np.sum(r[r <= tol] ** 2)
        if cnt < best_cnt or cnt == 0 or (cnt == best_cnt and not sse < best_sse):
            continue
        best, best_cnt, best_sse = np.append(n, -n @ pts[i]), cnt, sse
        w = cnt / len(pts)
        stop = 0 if w >= 1 else min(log_fail / np.log1p(-(w**3)), len(triples))
    return best, best_cnt


@pytest.mark.parametrize("probability", [1.0, 0.999, 0.9])
def test_segment_plane_matches_numpy_reference(probability):
    rng = np.random.default_rng(4)
    n_in, n_out = 600, 1400  # a noisy plane in uniform clutter, then shuffled
    uv = rng.uniform(-5, 5, size=(n_in, 2))
    normal = np.array([0.2, -0.3, 0.93])
    normal /= np.linalg.norm(normal)
    e1 = np.cross(normal, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    plane_pts = (
        uv[:, :1] * e1 + uv[:, 1:] * e2 + (1.5 + 0.01 * rng.standard_normal((n_in, 1))) * normal
    )
    pts = rng.permutation(np.vstack([plane_pts, rng.uniform(-5, 5, size=(n_out, 3))]))
    tol = 0.03
    plane, inl = segment_plane(pts, tol, 200, probability, np.random.default_rng(11))
    triples = sample_triples(np.random.default_rng(11), len(pts), 200)
    ref, ref_cnt = _ransac_reference(pts, tol, triples, probability)
    np.testing.assert_allclose(plane, ref, rtol=0, atol=1e-12)
    assert len(inl) == ref_cnt >= 0.9 * n_in
    r = np.abs(pts @ plane[:3] + plane[3])
    np.testing.assert_array_equal(inl, np.flatnonzero(r <= tol))  # no boundary points here
    assert abs(abs(plane[:3] @ normal) - 1) < 1e-3
    again = segment_plane(pts, tol, 200, probability, np.random.default_rng(11))
    np.testing.assert_array_equal(again[0], plane)
    np.testing.assert_array_equal(again[1], inl)


def test_segment_plane_degenerate_inputs():
    rng = np.random.default_rng(0)
    for m in (0, 1, 2):
        plane, inl = segment_plane(np.zeros((m, 3)), 0.1, 50, 0.99, rng)
        assert not plane.any() and len(inl) == 0
    line = np.outer(np.arange(10.0), [1.0, 2.0, 3.0])  # every triple collinear
    plane, inl = segment_plane(line, 0.1, 50, 0.99, rng)
    assert not plane.any() and len(inl) == 0
    square = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=float)
    plane, inl = segment_plane(square, 0.01, 50, 0.99, rng)  # all inliers: stops at once
    assert abs(plane[2]) == 1.0 and plane[3] == 0.0
    np.testing.assert_array_equal(inl, np.arange(4))


def test_sample_triples_distinct_and_uniform():
    tri = sample_triples(np.random.default_rng(1), 4, 48_000)
    assert tri.min() == 0 and tri.max() == 3
    assert np.all((tri[:, 0] != tri[:, 1]) & (tri[:, 0] != tri[:, 2]) & (tri[:, 1] != tri[:, 2]))
    _, counts = np.unique(tri, axis=0, return_counts=True)
    assert len(counts) == 24  # the 4 * 3 * 2 ordered triples, 2000 expected each
    assert np.all(np.abs(counts - 2000) < 5 * np.sqrt(2000))


def _floor_grid(step_deg: float, height: float = 1.8) -> np.ndarray:
    """(H, W, 3) a level floor ``height`` m below the sensor on square pixels ``step_deg``
    apart, elevations -17 to -10.5 deg (incidence 10.5-17 deg), azimuths +-30 deg."""
    el = np.radians(np.arange(-17.0, -10.5 + 1e-9, step_deg))
    az = np.radians(np.arange(-30.0, 30.0 + 1e-9, step_deg))
    E, A = np.meshgrid(el, az, indexing="ij")
    d = np.stack([np.cos(E) * np.cos(A), np.cos(E) * np.sin(A), np.sin(E)], axis=2)
    P = d * (height / -d[..., 2:3])
    P[..., 2] = -height
    return np.ascontiguousarray(P)


def test_grazing_gap_keeps_a_sparse_floor_and_leaves_fine_pixels_unscaled():
    """``organised_gap: grazing`` on 2 deg pixels (a 16-beam lidar's rows): a floor seen at
    10.5-17 deg incidence is one piece, where the unscaled rule cuts it (rows 8 and 9.4 m
    away are 1.4 m apart, over the 1 m limit); on 0.4 deg pixels (a 64-beam lidar's) the
    step it scales by lies beyond a pixel's diagonal, so the rule is the unscaled one."""
    from planodom.extraction.lidar.organised import _gap_step

    cfg = ExtractionConfig(organised_gap="grazing")
    step = _gap_step(cfg, np.radians(0.7))
    assert step == pytest.approx(0.1 * np.sin(np.radians(10.0)), rel=1e-12)
    assert step > np.sqrt(2) * np.radians(0.4)
    assert _gap_step(ExtractionConfig(organised_gap="range"), np.radians(0.7)) == 0.0
    P = _floor_grid(2.0)
    n, e, ok = _pixel_normals(P, 3, 1, 0.002, 0.02, 3.0)
    args = (0.02, 3.0, np.radians(cfg.region_normal_floor_deg), cfg.min_gap_m,
            cfg.gap_range_ratio, np.zeros(3), 3)  # fmt: skip
    assert _grow_pieces(P, n, e, ok, *args, 0.0)[1] == 2
    assert _grow_pieces(P, n, e, ok, *args, step)[1] == 1
