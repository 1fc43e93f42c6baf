"""The lidar path's robust fits of candidate sets (:func:`planodom.extraction.lidar.path.
fit_candidates`) against one selection per set, packed plane by plane."""

from __future__ import annotations

import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction.lidar.path import _pack, fit_candidates
from planodom.extraction.planes.fit import robust_plane_fits


def _per_set(candidates, points, config):
    """The fits by one selection per kept set, packed from lists (the path before its
    one mask over all sets)."""
    big = [c for c in candidates if len(c) >= config.min_plane_points]
    bounds = np.zeros(len(big) + 1, dtype=np.int64)
    np.cumsum([len(c) for c in big], out=bounds[1:])
    flat = np.concatenate(big)
    inlier, ok, centroid, evals, evecs = robust_plane_fits(
        points[flat], bounds, config.inlier_sigma_factor
    )
    fits, sets = [], []
    for g in range(len(big)):
        mine = flat[bounds[g] : bounds[g + 1]][inlier[bounds[g] : bounds[g + 1]]]
        if ok[g] and len(mine) >= config.min_plane_points:
            sets.append(mine)
            fits.append((centroid[g], evals[g], evecs[g]))
    return _pack(sets, fits, None), len(candidates) - len(sets)


def _scene(rng):
    """Noisy points of five planes and of clutter; candidate sets mixing them, some too
    small, some all clutter (their fits fail or keep too few)."""
    pts, sets, k = [], [], 0
    for _ in range(5):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        e1 = np.cross(n, [0.3, 0.5, 0.8])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        m = int(rng.integers(20, 400))
        uv = rng.uniform(-3, 3, (m, 2))
        p = uv @ np.vstack([e1, e2]) + rng.normal(scale=0.01, size=(m, 1)) * n + rng.normal(size=3)
        pts.append(p)
        sets.append(np.arange(k, k + m))
        k += m
    pts.append(rng.uniform(-5, 5, (300, 3)))  # clutter
    out = [np.sort(np.concatenate([s, k + rng.choice(300, 15, replace=False)])) for s in sets]
    out += [k + np.arange(0, 8), k + np.arange(10, 70), np.arange(3)]
    pts.append(_trimmed_below(rng))  # kept by size, dropped by its fit
    out.append(k + 300 + np.arange(30))
    return np.vstack(pts), [out[i] for i in rng.permutation(len(out))]


def _trimmed_below(rng):
    """(30, 3): 26 points near a plane and 4 far off it (26 inliers remain)."""
    flat = np.column_stack([rng.uniform(-5, 5, (26, 2)), rng.normal(scale=0.001, size=26)])
    return np.vstack([flat, np.column_stack([rng.uniform(-5, 5, (4, 2)), rng.uniform(0.5, 1, 4)])])


def test_fit_candidates_equal_the_per_set_selections():
    rng = np.random.default_rng(31)
    config = ExtractionConfig(min_plane_points=30)
    seen_dropped = False
    for _ in range(20):
        points, candidates = _scene(rng)
        got, n_got = fit_candidates(candidates, points, config)
        want, n_want = _per_set(candidates, points, config)
        assert n_got == n_want
        seen_dropped |= n_got > 0
        for name in ("count", "centroid", "offset", "evals", "evecs", "inliers", "bounds",
                     "outline"):  # fmt: skip
            a, b = getattr(got, name), getattr(want, name)
            assert a.dtype == b.dtype and a.shape == b.shape, name
            assert a.tobytes() == b.tobytes(), name
        assert got.n_rows is None and got.incidence is None
    assert seen_dropped


def test_fit_candidates_without_a_kept_set():
    """A set of 26 points near a plane and 4 far off it keeps 26 inliers, under 30."""
    points = _trimmed_below(np.random.default_rng(32))
    config = ExtractionConfig(min_plane_points=30)
    got, n = fit_candidates([np.arange(30), np.arange(5)], points, config)
    want, _ = _per_set([np.arange(30), np.arange(5)], points, config)
    assert n == 2 and len(got) == 0 == len(want)
    for name in ("count", "centroid", "offset", "evals", "evecs", "inliers", "bounds"):
        assert getattr(got, name).shape == getattr(want, name).shape, name
        assert getattr(got, name).dtype == getattr(want, name).dtype, name
