"""The time windows' compiled passes (:mod:`planodom.extraction.rig2d.window_kernels`)
against the numpy code they replace (:mod:`planodom.extraction.rig2d.windows`), to the
bit, on simulated windowed epochs and drawn inputs."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import planodom.extraction.rig2d.windows as windows
from planodom.extraction.planes.builder import PlaneFits
from planodom.extraction.rig2d.window_kernels import compiled_sweep_timing
from planodom.scan import Scan


def _same(a: object, b: object) -> bool:
    return np.asarray(a).tobytes() == np.asarray(b).tobytes()


def _same_timing(a: windows.SweepTiming, b: windows.SweepTiming) -> bool:
    return (
        type(a.count) is type(b.count)
        and a.count == b.count
        and _same(a.period, b.period)
        and _same(a.duration, b.duration)
    )


def _drawn_scan(rng: np.random.Generator, rings: int, sweeps: int, per: int):
    """A scan of ``rings`` rings (ids with gaps) swept ``sweeps`` times each, ``per``
    beams a sweep along an arc (the angle restarts each sweep), in ring order, with
    times of equal steps, ties and a dropped beam; its segments' order and points."""
    ids = np.sort(rng.choice(np.arange(40), size=rings, replace=False))
    pts, ring, t = [], [], []
    for r in ids:
        for s in range(sweeps):
            ang = np.linspace(-1.4, 1.4, per) + rng.normal(scale=1e-3, size=per)
            rng_m = rng.uniform(3.0, 20.0, size=per)
            z = 0.3 * r * np.ones(per)
            pts.append(np.column_stack([rng_m * np.cos(ang), rng_m * np.sin(ang), z]))
            tt = s * 0.013 + np.linspace(0.0, 0.0067, per)
            tt[rng.integers(0, per)] = tt[0]  # a tie
            t.append(tt - 0.05)
            ring.append(np.full(per, r))
    points = np.concatenate(pts)
    ring_a, t_a = np.concatenate(ring).astype(np.int32), np.concatenate(t)
    keep = np.ones(len(t_a), dtype=bool)
    keep[rng.integers(0, len(t_a))] = False
    points, ring_a, t_a = points[keep], ring_a[keep], t_a[keep]
    scan = Scan(points, ring=ring_a, t=t_a)
    order = np.argsort(ring_a, kind="stable").astype(np.int64)
    segs = SimpleNamespace(order=order, points=np.ascontiguousarray(points[order]))
    return scan, segs


@pytest.mark.parametrize("seed", range(6))
def test_sweep_timing_compiled_equals_numpy_on_drawn_scans(seed):
    rng = np.random.default_rng(seed)
    scan, segs = _drawn_scan(rng, int(rng.integers(1, 5)), int(rng.integers(1, 6)), 40)
    got = windows.sweep_timing(scan, segs)
    assert compiled_sweep_timing(scan.ring, scan.t, segs.order, segs.points) is not None
    assert _same_timing(got, windows.numpy_sweep_timing(scan, segs))


def test_sweep_timing_leaves_rings_out_of_order_and_other_times_to_numpy():
    rng = np.random.default_rng(9)
    scan, segs = _drawn_scan(rng, 3, 2, 30)
    shuffled = SimpleNamespace(order=segs.order[::-1].copy(), points=segs.points[::-1].copy())
    assert compiled_sweep_timing(scan.ring, scan.t, shuffled.order, shuffled.points) is None
    got = windows.sweep_timing(scan, shuffled)
    assert _same_timing(got, windows.numpy_sweep_timing(scan, shuffled))
    t32 = scan.t.astype(np.float32)
    assert compiled_sweep_timing(scan.ring, t32, segs.order, segs.points) is None


def _drawn_fits(rng: np.random.Generator, N: int, G: int) -> tuple[PlaneFits, np.ndarray]:
    points = rng.normal(size=(N, 3)) * 10.0
    sizes = rng.integers(0, 30, size=G)
    sizes[0] = 0  # a fit without inliers
    bounds = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    K = int(bounds[-1])
    inliers = rng.integers(0, N, size=K).astype(np.int64)
    outline = rng.uniform(size=K) < 0.4
    if G > 1:
        outline[bounds[1] : bounds[2]] = False  # one without outline points
    centroid = rng.normal(size=(G, 3))
    fits = PlaneFits(
        count=sizes.astype(np.int64), centroid=centroid, offset=np.zeros(G),
        evals=np.ones((G, 3)), evecs=np.tile(np.eye(3), (G, 1, 1)), inliers=inliers,
        bounds=bounds, outline=outline,
    )  # fmt: skip
    return fits, points


@pytest.mark.parametrize("seed", range(5))
def test_support_radii_compiled_equals_numpy(seed):
    rng = np.random.default_rng(seed)
    fits, points = _drawn_fits(rng, 200, int(rng.integers(1, 12)))
    points[rng.integers(0, 200)] = fits.centroid[-1]  # a zero distance, maybe an outline
    assert _same(windows.support_radii(fits, points), windows.numpy_support_radii(fits, points))


def test_windowed_epochs_of_a_simulated_world_give_the_same_bits(monkeypatch):
    """World 426 at 2 cm, extracted without a twist (time windows): every sweep timing
    and support radius of its epochs equal numpy's."""
    from planodom.config import PlanodomConfig
    from planodom.experiments.generalisation import declared_sweep, world_for
    from planodom.extraction.pipeline import extract
    from planodom.simulation.random_world import simulate_world, world_fields

    w = world_for(426)
    cfg = declared_sweep(w, PlanodomConfig()).extraction
    run = world_fields(w, simulate_world(w, 0.02, n_epochs=4, all_fields=True))
    timings, radii = [], []
    timing, radius = windows.sweep_timing, windows.support_radii

    def spy_timing(scan, segs):  # type: ignore[no-untyped-def]
        timings.append((timing(scan, segs), windows.numpy_sweep_timing(scan, segs)))
        return timings[-1][0]

    def spy_radii(fits, points):  # type: ignore[no-untyped-def]
        radii.append((radius(fits, points), windows.numpy_support_radii(fits, points)))
        return radii[-1][0]

    monkeypatch.setattr(windows, "sweep_timing", spy_timing)
    monkeypatch.setattr(windows, "support_radii", spy_radii)
    for scan in run.scans[1:]:
        extract(scan, cfg, None, run.rig.sensor_origins)
    assert len(timings) == 3 and radii
    assert all(_same_timing(a, b) for a, b in timings)
    assert all(_same(a, b) for a, b in radii)
