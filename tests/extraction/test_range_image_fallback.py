"""A range image that grows no candidate leaves the scan to RANSAC (a real cloud's grid
can be too sparse for pixel normals)."""

from __future__ import annotations

import numpy as np

from planodom.config import PlanodomConfig
from planodom.extraction.lidar import candidates as cand


def _ground_and_wall(seed: int = 0) -> np.ndarray:
    """(N, 3) m: a ground plane z = -1.8 and a wall x = 8 with 1 cm noise."""
    rng = np.random.default_rng(seed)
    g = np.c_[rng.uniform(-10, 10, (3000, 2)), np.full(3000, -1.8)]
    w = np.c_[np.full(2000, 8.0), rng.uniform(-10, 10, 2000), rng.uniform(-1.8, 3, 2000)]
    pts = np.r_[g, w]
    return pts + 0.01 * rng.standard_normal(pts.shape)


def test_no_grown_candidate_falls_back_to_ransac(monkeypatch):
    pts = _ground_and_wall()
    ring = np.zeros(len(pts), dtype=np.int64)
    t = np.linspace(0.0, 0.1, len(pts))
    monkeypatch.setattr(cand, "range_image_candidates", lambda *a, **k: [])
    found, _, _ = cand.lidar_candidates(pts, PlanodomConfig().extraction, ring, None, t)
    # the two true planes, by their points' membership (independent of the fit)
    sets = sorted(found, key=len, reverse=True)[:2]
    assert len(sets) == 2
    on_ground = [np.mean(pts[s, 2] < -1.7) for s in sets]
    on_wall = [np.mean(pts[s, 0] > 7.9) for s in sets]
    assert max(on_ground) > 0.95 and max(on_wall) > 0.95
