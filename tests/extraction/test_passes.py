"""The plane builder's two compiled calls against the stage-by-stage sequence they replace.

The reference is the sequence the builder ran before (SPEED2D7): ``fit_arrays``, the
kept fits, ``Epoch.viewpoints``, ``mean_incidences``, the orientation signs, the oriented
normals and offsets in numpy, then ``distinct_and_majority`` and ``support_polygons``.
Every output must be the same bits: on random fits with every viewpoint case, and on the
fits of simulated 2D-rig epochs.
"""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import ExtractionConfig
from planodom.extraction.epoch import Epoch
from planodom.extraction.planes import builder
from planodom.extraction.planes.builder import _COS45, PlaneFits
from planodom.extraction.planes.confidence import mean_incidences
from planodom.extraction.planes.fit import fit_arrays
from planodom.extraction.planes.passes import (
    _orientation_kernel,
    fits_views_signs,
    rows_labels_polygons,
    view_mode,
)
from planodom.extraction.planes.support import distinct_and_majority, support_polygons
from planodom.scan import Scan


def _reference(fits: PlaneFits, epoch: Epoch, cfg: ExtractionConfig) -> tuple:
    """The arrays of the builder's former stage-by-stage sequence."""
    G = len(fits)
    floor = cfg.covariance_sigma_floor_m
    max_var_n = float(np.radians(cfg.max_normal_sigma_deg) ** 2)
    normals = fits.evecs[:, :, 2]
    covs, width, rms, keep, scatter = fit_arrays(
        fits.evals, fits.evecs, fits.centroid, fits.count, floor**2, cfg.min_plane_points,
        cfg.min_plane_width_m, max_var_n,
    )  # fmt: skip
    kept = np.flatnonzero(keep)
    views = np.zeros((G, 3))
    views[:, 2] = cfg.viewpoint_height_m
    incidence = np.ones(G) if fits.incidence is None else fits.incidence.copy()
    if fits.incidence is None or epoch.origins is not None:
        inl, bnd = fits.inliers.astype(np.int64), fits.bounds.astype(np.int64)
        views[kept] = epoch.viewpoints(inl, bnd, kept, cfg.viewpoint_height_m)
        incidence[kept] = mean_incidences(epoch.points, inl, bnd, kept, views[kept], normals[kept])
    signs = _orientation_kernel(normals, fits.offset, fits.centroid, views, _COS45)
    n_or, d_or = signs[:, None] * normals, signs * fits.offset
    rows, truth = distinct_and_majority(
        epoch.scan.ring if fits.n_rows is None else None, epoch.scan.label, fits.inliers,
        fits.bounds, kept,
    )  # fmt: skip
    polygons = support_polygons(
        epoch.points, fits.inliers, fits.bounds, fits.outline, kept, fits.centroid, fits.evecs
    )
    return (covs, width, rms, kept, scatter, views, incidence, n_or, d_or), (rows, truth, polygons)


def _fused(fits: PlaneFits, epoch: Epoch, cfg: ExtractionConfig) -> tuple:
    """The same arrays from the two compiled calls, as the builder makes them."""
    floor = cfg.covariance_sigma_floor_m
    points = np.ascontiguousarray(epoch.points, dtype=np.float64)
    inl = fits.inliers.astype(np.int64, copy=False)
    bnd = fits.bounds.astype(np.int64, copy=False)
    mode, org, ring, t, xi = view_mode(epoch)
    first = fits_views_signs(
        fits.evals, fits.evecs, fits.centroid, fits.count, fits.offset, floor**2,
        cfg.min_plane_points, cfg.min_plane_width_m,
        float(np.radians(cfg.max_normal_sigma_deg) ** 2), points, inl, bnd,
        np.ones(len(fits)) if fits.incidence is None else fits.incidence,
        fits.incidence is None or epoch.origins is not None, mode,
        float(cfg.viewpoint_height_m), org, ring, t, xi, _COS45,
    )  # fmt: skip
    second = rows_labels_polygons(
        epoch, points, inl, bnd, fits.outline, first[3], fits.centroid, fits.evecs,
        fits.n_rows is None,
    )  # fmt: skip
    return first, second


def _assert_same_bits(got: tuple, ref: tuple) -> None:
    for a, b in zip(got[0], ref[0], strict=True):
        np.testing.assert_array_equal(a, b, strict=True)
    rows, truth, polygons = got[1]
    np.testing.assert_array_equal(rows, ref[1][0], strict=True)
    np.testing.assert_array_equal(truth, ref[1][1], strict=True)
    assert len(polygons) == len(ref[1][2])
    for p, q in zip(polygons, ref[1][2], strict=True):
        np.testing.assert_array_equal(p, q, strict=True)


def _random_fits(rng: np.random.Generator, N: int, G: int, incidence: bool) -> PlaneFits:
    """G fits of random inlier sets of N points: some pass the plane tests, some not
    (few points, thin, uncertain), strided eigenvector columns as the 2D-rig path passes
    them, fits of no inliers."""
    evecs = np.linalg.qr(rng.normal(size=(G, 3, 3)))[0][:, :, ::-1]
    evals = np.sort(rng.uniform(0.0, 40.0, size=(G, 3)), axis=1)[:, ::-1]
    evals[:, 2] *= rng.choice([1e-6, 1e-3, 1.0], size=G)
    sizes = rng.integers(0, 300, G)
    sizes[0] = 0
    inliers = np.concatenate([rng.choice(N, k, replace=False) for k in sizes]).astype(np.int64)
    centroid = rng.normal(size=(G, 3)) * 5.0
    normal = evecs[:, :, 2]
    return PlaneFits(
        count=sizes.astype(np.int64), centroid=centroid,
        offset=-np.einsum("gi,gi->g", normal, centroid), evals=evals, evecs=evecs,
        inliers=inliers, bounds=np.r_[0, np.cumsum(sizes)].astype(np.int64),
        outline=rng.uniform(size=len(inliers)) < 0.6,
        incidence=rng.uniform(0.1, 1.0, G) if incidence else None,
        n_rows=None if rng.uniform() < 0.5 else rng.integers(1, 5, G),
    )  # fmt: skip


@pytest.mark.parametrize("origins", ["none", "one", "per_ring"])
@pytest.mark.parametrize("twisted", [False, True])
@pytest.mark.parametrize("incidence", [False, True])
def test_two_calls_equal_the_stage_sequence_on_random_fits(origins, twisted, incidence):
    """Every viewpoint case (no origins, one for all, one per ring; with and without a
    twist; the path's own incidence or none), labels with unlabelled points and ring ids
    of the scan's dtype: the same bits as the stage sequence, 20 random epochs each."""
    rng = np.random.default_rng(17)
    cfg = ExtractionConfig()
    for _ in range(20):
        N, G = int(rng.integers(300, 900)), int(rng.integers(1, 12))
        pts = rng.normal(0.0, 6.0, (N, 3))
        ring = rng.integers(0, 4, N).astype(rng.choice([np.int32, np.int64, np.uint8]))
        labels = np.where(rng.uniform(size=N) < 0.2, -1, rng.integers(0, 6, N))
        t = rng.uniform(-0.05, 0.05, N)
        org = {"none": None, "one": rng.normal(size=(1, 3)), "per_ring": rng.normal(size=(4, 3))}
        twist = rng.normal(size=6) * [0.3, 0.3, 2.0, 5.0, 1.0, 0.2] if twisted else None
        epoch = Epoch(Scan(pts, ring, t, labels), pts, org[origins], twist)
        fits = _random_fits(rng, N, G, incidence)
        _assert_same_bits(_fused(fits, epoch, cfg), _reference(fits, epoch, cfg))


@pytest.mark.parametrize(("world", "noise"), [(160, 0.02), (162, 0.006)])
def test_two_calls_equal_the_stage_sequence_on_simulated_epochs(monkeypatch, world, noise):
    """The fits the 2D-rig path hands the builder on simulated epochs (outdoor 160 at
    2 cm, indoor 162 at 6 mm, read-only deskewed points, sensor origins per ring), with
    and without a twist: the same bits as the stage sequence."""
    from planodom.config import PlanodomConfig
    from planodom.experiments.generalisation import declared_sweep, world_for
    from planodom.extraction.pipeline import extract
    from planodom.simulation.random_world import simulate_world, world_fields

    w = world_for(world)
    cfg = declared_sweep(w, PlanodomConfig()).extraction
    run = world_fields(w, simulate_world(w, noise, n_epochs=4, all_fields=True))
    seen: list[tuple[PlaneFits, Epoch]] = []
    build = builder.build_planes

    def spy(fits, epoch, sigma_m, config, adjust=None, narrow=None):  # type: ignore[no-untyped-def]
        seen.append((fits, epoch))
        return build(fits, epoch, sigma_m, config, adjust, narrow)

    monkeypatch.setattr("planodom.extraction.rig2d.path.build_planes", spy)
    twist = np.array([0.01, -0.02, 0.3, 4.0, 0.1, 0.0])
    for scan in run.scans:
        for xi in (None, twist):
            extract(scan, cfg, xi, run.rig.sensor_origins)
    assert len(seen) == 2 * len(run.scans) and all(len(f) for f, _ in seen)
    for fits, epoch in seen:
        _assert_same_bits(_fused(fits, epoch, cfg), _reference(fits, epoch, cfg))
