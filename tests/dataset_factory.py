"""Random scans and poses for the dataset tests: values that catch lossy storage."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from planodom.scan import Scan

ALL_FIELDS = ("ring", "t", "label")


def make_scan(rng: np.random.Generator, n: int = 50, fields=ALL_FIELDS) -> Scan:
    """Random scan with values that catch lossy storage (tiny, large, -0.0, int32 extremes);
    coordinates stay within the readers' 1e6 m."""
    pts = rng.normal(scale=20.0, size=(n, 3)) * 10.0 ** rng.integers(-8, 4, size=(n, 1))
    if n >= 3:
        pts[0, 0], pts[1, 1], pts[2, 2] = -0.0, 5e-324, -987654.3210987654
    label = rng.integers(-1, 40, n).astype(np.int32)
    if n >= 2:
        label[:2] = [np.iinfo(np.int32).min, np.iinfo(np.int32).max]
    extra = {
        "ring": rng.integers(0, 64, n).astype(np.int32),
        "t": rng.uniform(0.0, 0.1, n) + 1e-17,
        "label": label,
    }
    return Scan(pts, **{k: v for k, v in extra.items() if k in fields})


def float32_safe(scan: Scan) -> Scan:
    """``scan`` with coordinates clipped into float32 range."""
    return Scan(np.clip(scan.points, -1e30, 1e30), scan.ring, scan.t, scan.label)


def assert_same_scan(a: Scan, b: Scan) -> None:
    """Bit-exact equality of points and fields (also tells -0.0 from 0.0)."""
    assert a.points.dtype == b.points.dtype == np.float64
    assert a.points.shape == b.points.shape
    assert np.array_equal(a.points.view(np.uint64), b.points.view(np.uint64))
    for name in ALL_FIELDS:
        va, vb = getattr(a, name), getattr(b, name)
        assert (va is None) == (vb is None), name
        if va is not None:
            assert va.dtype == vb.dtype
            assert np.array_equal(va.view(np.uint8), vb.view(np.uint8)), name


def random_poses(rng: np.random.Generator, n: int) -> np.ndarray:
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3] = Rotation.random(n, random_state=rng).as_matrix()
    poses[:, :3, 3] = rng.normal(scale=100.0, size=(n, 3))
    return poses
