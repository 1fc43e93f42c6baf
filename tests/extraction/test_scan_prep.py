"""The compiled per-scan passes (:mod:`planodom.extraction.scan_prep`) answer as the numpy
forms they replace, to the bit: the ring order, the ring count and the points' checks,
on simulated 2D-rig epochs and on drawn edge cases; the numpy forms still answer what
the passes do not take."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.errors import GeometryError
from planodom.extraction import pipeline, scan_prep
from planodom.extraction.rig2d import segments


def _same_order(a: tuple, b: tuple) -> None:
    """Two ring orders ``(order, rings, times, timing)`` equal: every array's dtype and
    bytes, the times None together, the timing's values and types."""
    for x, y in zip(a[:2], b[:2], strict=True):
        assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()
    assert (a[2] is None) == (b[2] is None)
    if a[2] is not None:
        assert a[2].dtype == b[2].dtype and a[2].tobytes() == b[2].tobytes()
    assert a[3] == b[3] and [type(v) for v in a[3]] == [type(v) for v in b[3]]
    assert np.isnan(a[3][0]) == np.isnan(b[3][0])


def _drawn_rings(rng: np.random.Generator, n: int, n_rings: int, dtype: type) -> np.ndarray:
    """Ring ids of ``n`` points: runs of one ring interleaved at random, offset ids."""
    runs = rng.integers(0, n_rings, size=n // 7 + 1)
    ring = np.repeat(runs, 7)[:n] + rng.integers(0, 3)
    return ring.astype(dtype)


@pytest.fixture(scope="module")
def simulated_scans() -> list:
    """12 epochs of world 162 (2D rig, indoor) at 2 cm, and 4 of world 160 (outdoor)."""
    from planodom.experiments.generalisation import world_for
    from planodom.simulation.random_world import simulate_world, world_fields

    scans = []
    for w, n in ((162, 12), (160, 4)):
        world = world_for(w)
        run = world_fields(world, simulate_world(world, 0.02, n_epochs=n, all_fields=True))
        scans += list(run.scans)
    return scans


def test_simulated_scans_order_count_and_check_as_numpy(simulated_scans: list) -> None:
    for scan in simulated_scans:
        got = scan_prep.compiled_ring_order(scan.ring, scan.t)
        assert got is not None  # these scans take the compiled pass
        _same_order(got, segments.numpy_ring_order(scan.ring, scan.t))
        _same_order(scan_prep.compiled_ring_order(scan.ring, None) or (),
                    segments.numpy_ring_order(scan.ring, None))  # fmt: skip
        assert scan_prep.compiled_count_rings(scan.ring) == pipeline.numpy_count_rings(scan.ring)
        assert scan_prep.points_times_finite(scan.points, scan.t, pipeline.MAX_COORDINATE_M)
        pipeline.numpy_check_points_times(scan.points, scan.t)  # passes there too


@pytest.mark.parametrize("dtype", [np.int32, np.int64])
@pytest.mark.parametrize("n", [0, 1, 2, 3, 50, 2000])
def test_drawn_rings_order_as_numpy(dtype: type, n: int) -> None:
    rng = np.random.default_rng(n)
    for n_rings in (1, 2, 4, 40):
        ring = _drawn_rings(rng, n, n_rings, dtype)
        # times with ties, backward steps and repeated values (the timing's cases)
        t = np.round(rng.uniform(-0.05, 0.05, n), 3)
        t[: n // 2] = np.sort(t[: n // 2])
        for times in (t, None, np.zeros(n), np.sort(t)):
            got = scan_prep.compiled_ring_order(ring, times)
            assert got is not None
            _same_order(got, segments.numpy_ring_order(ring, times))
        sorted_ring = np.sort(ring)  # already in order: the identity permutation
        _same_order(scan_prep.compiled_ring_order(sorted_ring, t) or (),
                    segments.numpy_ring_order(sorted_ring, t))  # fmt: skip


def test_negative_ids_and_wide_spans() -> None:
    ring = np.array([5, -3, 5, 0, -3, 65531], dtype=np.int64)
    t = np.linspace(0.0, 0.01, len(ring))
    _same_order(scan_prep.compiled_ring_order(ring, t) or (), segments.numpy_ring_order(ring, t))
    # ids spanning 2**16 values or more, other dtypes, times of another length or
    # dtype: left to numpy
    wide = np.array([70000, 0, 3], dtype=np.int64)
    assert scan_prep.compiled_ring_order(wide, None) is None
    assert scan_prep.compiled_ring_order(ring.astype(np.uint16), None) is None
    assert scan_prep.compiled_ring_order(ring, t[:-1]) is None
    assert scan_prep.compiled_ring_order(ring, t.astype(np.float32)) is None
    # the memoised entry point answers either way, as numpy
    for r, tt in ((wide, None), (ring.astype(np.uint16), t), (ring, t.astype(np.float32))):
        _same_order(segments.ring_order(r, tt), segments.numpy_ring_order(r, tt))


def test_ring_counts_as_numpy() -> None:
    rng = np.random.default_rng(7)
    cases = [np.zeros(0, np.int64), np.array([3]), np.array([0, 65535, 0]), np.arange(40)]
    cases += [rng.integers(0, k, size=300) for k in (1, 3, 64, 200)]
    for ring in cases:
        for dtype in (np.int32, np.int64):
            r = ring.astype(dtype)
            assert scan_prep.compiled_count_rings(r) == pipeline.numpy_count_rings(r)
            assert pipeline.count_rings(r) == pipeline.numpy_count_rings(r)
    for ring in (np.array([-1, 0, 2]), np.array([0, 65536]), np.array([1, 2], np.uint8)):
        assert scan_prep.compiled_count_rings(ring) is None  # numpy's form answers
        assert pipeline.count_rings(ring) == len(np.unique(ring))


def _numpy_passes(pts: np.ndarray, t: np.ndarray | None) -> bool:
    try:
        pipeline.numpy_check_points_times(pts, t)
    except GeometryError:
        return False
    return True


def test_points_checks_decide_as_numpy() -> None:
    rng = np.random.default_rng(11)
    limit = pipeline.MAX_COORDINATE_M
    base = rng.uniform(-50.0, 50.0, (40, 3))
    t = np.linspace(-0.05, 0.05, 40)
    bad_values = (np.nan, np.inf, -np.inf, limit, -limit, np.nextafter(limit, np.inf),
                  -np.nextafter(limit, np.inf), 2 * limit)  # fmt: skip
    for v in bad_values:
        for k in (0, 17, 119):
            pts = base.copy()
            pts.flat[k] = v
            got = scan_prep.points_times_finite(pts, t, limit)
            assert got == _numpy_passes(pts, t), (v, k)
    for v in (np.nan, np.inf, -np.inf, 1e300):
        tt = t.copy()
        tt[5] = v
        assert scan_prep.points_times_finite(base, tt, limit) == _numpy_passes(base, tt)
    assert scan_prep.points_times_finite(base, None, limit) is True
    assert scan_prep.points_times_finite(np.zeros((0, 3)), None, limit) is True
    # not float64 C-contiguous: left to numpy
    assert scan_prep.points_times_finite(np.asfortranarray(base), t, limit) is None
    assert scan_prep.points_times_finite(base.astype(np.float32), t, limit) is None
    assert scan_prep.points_times_finite(base, t.astype(np.float32), limit) is None


def test_the_checks_still_word_their_errors() -> None:
    pts = np.zeros((4, 3))
    pts[2, 1] = np.nan
    with pytest.raises(GeometryError, match="1 of 4 points with NaN"):
        pipeline._check_points_times.__wrapped__(pts, None)
    pts[2, 1] = 2e6
    with pytest.raises(GeometryError, match="scan coordinates reach 2e"):
        pipeline._check_points_times.__wrapped__(pts, None)
    with pytest.raises(GeometryError, match="scan times t contain NaN"):
        pipeline._check_points_times.__wrapped__(np.zeros((2, 3)), np.array([0.0, np.inf]))
