"""The square-pixel image of an unorganised cloud (planodom.extraction.lidar.organised):
the pixel normals' window capped in angle, against the true walls of a sparse lidar."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import ExtractionConfig
from planodom.extraction import extract
from planodom.extraction.lidar.organised import _row_azimuth_order, organised_window
from planodom.extraction.lidar.path import _rows_spanned
from planodom.scan import Scan

from .synth_scans import plane_errors, planes_in_base, rect, scan_lidar


def _corner_buildings() -> list:
    """Ground (id 0) and six square buildings 10 m wide and 8 m high, 30-36 m away all
    around, each turned 45 deg to the line of sight: two faces of each are seen, meeting
    at a corner, each about 13 deg of azimuth (6-7 pixels of a 16-beam lidar's 2 deg
    rows)."""
    scene = [rect([0, 0, 0], [0, 0, 1], up=[1, 0, 0], half_u=80, half_v=80)]
    for k in range(6):
        yaw, dist = np.radians(60.0 * k + 10.0), 30.0 + 6.0 * (k % 2)
        centre = dist * np.array([np.cos(yaw), np.sin(yaw), 0.0]) + [0, 0, 4.0]
        for face in range(4):
            a = yaw + np.radians(45.0 + 90.0 * face)
            out = np.array([np.cos(a), np.sin(a), 0.0])
            scene.append(rect(centre + 5.0 * out, out, half_u=5.0, half_v=4.0))
    return scene


def test_window_is_capped_in_angle():
    """``region_window`` pixels, at most ``organised_window_deg`` of azimuth, at least one."""
    cfg = ExtractionConfig()
    assert cfg.region_window == 3 and cfg.organised_window_deg == 1.5
    assert organised_window(cfg, 180) == 1  # 2 deg pixels: 16 beams
    assert organised_window(cfg, 847) == 3  # 0.425 deg pixels: 64 beams, 1.3 deg
    assert organised_window(cfg, 500) == 2  # 0.72 deg: 2 pixels = 1.44 deg
    assert organised_window(cfg, 36) == 1  # 10 deg pixels: never under one
    assert organised_window(cfg.model_copy(update={"organised_window_deg": None}), 180) == 3


def _faces_seen_and_found(sigma: float, window_deg: float | None) -> tuple[set, list]:
    """The faces a 16-beam cloud without rings or times sees (60 points or more) and the
    planes extracted from it with ``organised_window_deg`` = ``window_deg``."""
    scene = _corner_buildings()
    raw = scan_lidar(scene, sigma=sigma, seed=3, n_beams=16, n_azimuth=512, height=0.8,
                     with_ring=False)  # fmt: skip
    scan = Scan(raw.points, None, None, raw.label)
    ids, counts = np.unique(raw.label, return_counts=True)
    seen = {int(i) for i, c in zip(ids, counts, strict=True) if c >= 60 and i > 0}
    cfg = ExtractionConfig(range_noise_m=max(sigma, 0.002), estimate_noise=False)
    cfg = cfg.model_copy(update={"organised_window_deg": window_deg})
    return seen, extract(scan, cfg).planes


@pytest.mark.parametrize("sigma", [0.006, 0.02])
def test_sparse_lidar_finds_every_face_of_narrow_buildings(sigma):
    """Every face seen is found, each within its noise of the truth."""
    seen, planes = _faces_seen_and_found(sigma, 1.5)
    assert len(seen) == 12  # two faces per building
    assert seen <= {p.truth_id for p in planes}
    ang, off = plane_errors(planes, planes_in_base(_corner_buildings()))
    assert np.degrees(ang) < 0.5 and off < 0.05


def test_uncapped_window_loses_the_faces():
    """The same cloud at 6 mm with the window uncapped (3 pixels = 6 deg on each side):
    the pixel normals straddle the corners and half the faces or more are lost (at 2 cm
    the wider normal tolerance lets them grow anyway)."""
    seen, planes = _faces_seen_and_found(0.006, None)
    assert len(seen & {p.truth_id for p in planes}) <= 6


@pytest.mark.parametrize("seed", range(3))
def test_row_azimuth_order_is_numpys_lexsort(seed):
    """The order of the noise estimate: by row, then azimuth, ties in index order (rings
    in firing order, shuffled, with repeated azimuths, a missing row, negative rows)."""
    rng = np.random.default_rng(seed)
    n, H = 4992, 16
    az = np.tile(np.linspace(-np.pi, np.pi, n // H, endpoint=False), H)
    az = np.roll(az, 37) + rng.normal(0, 1e-4, n) * (rng.random(n) < 0.5)  # ties kept
    rows = np.repeat(np.arange(H), n // H)
    rows[rows == 5] = 6  # no row 5
    for perm in (np.arange(n), rng.permutation(n)):
        rel = np.column_stack([np.cos(az), np.sin(az), rng.normal(size=n)])[perm] * 7.0
        r = rows[perm].astype(np.int64)
        want = np.lexsort((np.arctan2(rel[:, 1], rel[:, 0]), r))
        assert np.array_equal(_row_azimuth_order(rel, r), want)
        assert np.array_equal(_row_azimuth_order(rel, r - 3), want)  # numpy's lexsort


def test_rows_spanned_count_distinct_rows():
    rng = np.random.default_rng(0)
    rows = rng.integers(0, 32, size=3000)
    cands = [rng.choice(3000, size=k, replace=False) for k in (3, 50, 700, 2999)]
    want = [len(np.unique(rows[c])) for c in cands]
    assert _rows_spanned(cands, rows).tolist() == want
    assert _rows_spanned(cands, rows - 1).tolist() == want  # negative: np.unique per set
    assert _rows_spanned([], rows).tolist() == []
