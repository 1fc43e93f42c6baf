"""The builder's planes and set assembled at once (:mod:`planodom.extraction.planes.assembly`)
against what the constructors make: ``Plane.__post_init__``'s checks and scaling, and
``PlaneSet.from_planes`` of the planes, to the bit."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import planodom.extraction.planes.builder as builder
import planodom.planes as planes_module
from planodom.errors import GeometryError
from planodom.extraction.planes.assembly import kept_set, made, unit_rows
from planodom.geometry import Plane, PlaneSupport
from planodom.planes import PlaneSet

_FIELDS = ("normals", "offsets", "weights", "centroids", "radii", "covariances", "narrow")


def _same_bits(a: object, b: object) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    return type(a) is type(b) and (a == b or (a != a and b != b))


def _same_plane(p: Plane, q: Plane) -> None:
    assert set(vars(p)) == set(vars(q)) == {f.name for f in dataclasses.fields(Plane)}
    for name in vars(p):
        x, y = getattr(p, name), getattr(q, name)
        if isinstance(x, PlaneSupport):
            assert set(vars(x)) == {f.name for f in dataclasses.fields(PlaneSupport)}
            assert all(_same_bits(getattr(x, f), getattr(y, f)) for f in vars(x)), name
        else:
            assert _same_bits(x, y), name


def _same_set(a: PlaneSet, b: PlaneSet) -> None:
    for name in _FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            assert _same_bits(x, y) and x.flags.c_contiguous and x.flags.writeable, name


def _rows(rng: np.random.Generator, G: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Normals of all lengths (unit, tiny, huge, zero, non-finite), offsets and confidences
    at and beyond their limits."""
    n = rng.normal(size=(G, 3)) * 10.0 ** rng.uniform(-14, 3, size=(G, 1))
    n[::7] /= np.linalg.norm(n[::7], axis=1)[:, None]
    n[1::11] = 0.0
    n[2::13, 1] = np.nan
    n[3::17, 2] = np.inf
    n[4::19] = [1e200, 0.0, 0.0]  # its square overflows: the constructor decides
    n[5::23] = [-0.0, 0.0, 1e-12]
    d = rng.normal(size=G) * 20.0
    d[6::29] = np.inf
    c = rng.uniform(0.0, 1.0, size=G)
    c[7::31], c[8::31], c[9::31], c[10::31] = 1.0, 0.0, np.nextafter(1.0, 2.0), np.nan
    return np.ascontiguousarray(n), d, c


@pytest.mark.parametrize("seed", range(4))
def test_unit_rows_check_and_scale_as_the_constructor(seed):
    """Each fit: passes exactly when ``Plane(n, d, confidence=c)`` does (or its square
    overflows, then the constructor is left to decide), and then gives its normal and
    offset to the bit, signed zeros included."""
    rng = np.random.default_rng(seed)
    n, d, c = _rows(rng, 400)
    for g in range(len(d)):
        ok, un, ud = unit_rows(n, d, c, np.array([g], dtype=np.int64))
        try:
            with np.errstate(over="ignore"):
                p = Plane(n[g], float(d[g]), confidence=float(c[g]))
        except GeometryError:
            assert not ok
            continue
        if not ok:
            with np.errstate(over="ignore"):
                assert not np.isfinite(n[g] @ n[g])
            continue
        assert _same_bits(un[0], p.normal) and _same_bits(float(ud[0]), p.offset)


def test_unit_rows_of_many_kept_fits_at_once():
    rng = np.random.default_rng(7)
    n = rng.normal(size=(50, 3))
    d, c = rng.normal(size=50), rng.uniform(0.1, 1.0, size=50)
    kept = np.array([3, 0, 49, 17, 17], dtype=np.int64)
    ok, un, ud = unit_rows(n, d, c, kept)
    assert ok
    for k, g in enumerate(kept):
        p = Plane(n[g], float(d[g]), confidence=float(c[g]))
        assert _same_bits(un[k], p.normal) and _same_bits(float(ud[k]), p.offset)
    assert unit_rows(n, d, c, np.zeros(0, dtype=np.int64))[0]
    c[17] = 0.0
    assert not unit_rows(n, d, c, kept)[0]


def test_made_equals_the_constructor_for_checked_values():
    support = PlaneSupport(np.ones(3), np.zeros((0, 3)), 5, np.eye(3), 2, None)
    fields = {"normal": np.array([0.0, 0.6, 0.8]), "offset": -2.5, "covariance": np.eye(4),
              "confidence": 0.5, "support": support, "truth_id": 3, "deskew_jacobian": None,
              "narrow": True}  # fmt: skip
    _same_plane(made(Plane, dict(fields)), Plane(**fields))
    kept = {f.name: getattr(support, f.name) for f in dataclasses.fields(PlaneSupport)}
    _same_plane(made(Plane, {**fields, "support": made(PlaneSupport, kept)}), Plane(**fields))


def test_kept_set_is_from_planes_of_the_planes():
    rng = np.random.default_rng(1)
    G = 9
    n, d, c = rng.normal(size=(G, 3)), rng.normal(size=G), rng.uniform(0.1, 1.0, size=G)
    covs, cen = rng.normal(size=(G, 4, 4)), rng.normal(size=(G, 3))
    narrow = rng.uniform(size=G) < 0.3
    kept = np.array([8, 2, 5, 0], dtype=np.int64)
    polys = [rng.normal(size=(m, 3)) for m in (4, 0, 7, 3)]
    ok, un, ud = unit_rows(n, d, c, kept)
    for nar in (narrow, None, np.zeros(G, dtype=bool)):
        got = kept_set(un, ud, c, covs, cen, polys, nar, kept)
        planes = [
            Plane(n[g], float(d[g]), covs[g], float(c[g]),
                  PlaneSupport(cen[g].copy(), polys[k], 10),
                  narrow=nar is not None and bool(nar[g]))
            for k, g in enumerate(kept)
        ]  # fmt: skip
        _same_set(got, PlaneSet.from_planes(planes))
    assert not np.shares_memory(got.normals, un)


def test_a_handed_set_serves_its_very_planes_once():
    rng = np.random.default_rng(2)
    planes = [Plane(rng.normal(size=3), float(rng.normal())) for _ in range(4)]
    ref = PlaneSet.from_planes(planes)
    planes_module.hand_over(planes, ref)
    assert PlaneSet.from_planes(list(planes)) is ref
    assert PlaneSet.from_planes(planes) is not ref  # once
    planes_module.hand_over(planes, ref)
    assert PlaneSet.from_planes(planes[::-1]) is not ref  # other order: built afresh
    assert PlaneSet.from_planes(planes) is not ref  # and dropped
    planes_module.hand_over(planes, ref)
    planes_module.reorder_handed(planes, [2, 0, 3, 1])
    order = [planes[i] for i in (2, 0, 3, 1)]
    _same_set(PlaneSet.from_planes(order), PlaneSet.from_planes(order))
    planes_module.hand_over(planes, ref)
    planes_module.reorder_handed(planes[:3], [0, 1, 2])  # not its planes: nothing moves
    assert PlaneSet.from_planes(planes) is ref


@pytest.mark.parametrize(("world", "noise"), [(420, 0.02), (162, 0.006)])
def test_extractions_give_the_constructors_planes_and_set(monkeypatch, world, noise):
    """Simulated 2D-rig epochs (outdoor 420 at 2 cm, indoor 162 at 6 mm), without a
    twist (time windows) and with one: every plane the same bits as the builder makes
    by the constructors (``unit_rows`` failing), and the set the extraction hands over
    the same bits as ``from_planes`` of its planes, in the extraction's order."""
    from planodom.config import PlanodomConfig
    from planodom.experiments.generalisation import declared_sweep, world_for
    from planodom.extraction.pipeline import extract
    from planodom.simulation.random_world import simulate_world, world_fields

    w = world_for(world)
    cfg = declared_sweep(w, PlanodomConfig()).extraction
    run = world_fields(w, simulate_world(w, noise, n_epochs=4, all_fields=True))
    twist = np.array([0.01, -0.02, 0.3, 4.0, 0.1, 0.0])
    fast, handed = [], []
    for scan in run.scans:
        for xi in (None, twist):
            got = extract(scan, cfg, xi, run.rig.sensor_origins)
            fast.append(got.planes)
            handed.append(planes_module._HANDED[1] if got.planes else None)
            if got.planes:
                planes_module._HANDED[:] = [None, None]
                _same_set(handed[-1], PlaneSet.from_planes(got.planes))
    assert sum(len(p) for p in fast) > 10
    unit = builder.unit_rows
    monkeypatch.setattr(builder, "unit_rows", lambda *a: (False, *unit(*a)[1:]))
    k = 0
    for scan in run.scans:
        for xi in (None, twist):
            slow = extract(scan, cfg, xi, run.rig.sensor_origins).planes
            assert len(slow) == len(fast[k])
            for p, q in zip(fast[k], slow, strict=True):
                _same_plane(p, q)
            k += 1
