"""The solve's translation in two compiled calls gives the numpy path's bits.

Every solve of seeded synthetic epochs (and of a short simulated 2D-rig run) is captured
at the solver's ``_measured_translation`` and answered twice: by
:func:`planodom.odometry.fused_translation.fused_translation` and by the solver's numpy
path (``translation_elements``, ``height_elements``, ``_elements_translation``). Their
outputs must be equal to the last bit (every array's bytes, every scalar); a fused path
that changed one operation's order, or dropped a case, fails here.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from planes_factory import (
    observed_pair,
    random_motion,
    world_planes,
)

import planodom.odometry.fused_translation as fused_module
import planodom.odometry.solver as solver
from planodom.config import PlanodomConfig
from planodom.odometry.fused_translation import (
    _pairwise_sum,
    _spread_kernel,
    fused_translation,
)


def _numpy_path(args: tuple) -> tuple:
    """The solver's numpy path for the captured ``args``."""
    prev, curr, R, pp, cp, ij, method, bounds, cfg = args
    ocfg = cfg.odometry
    elems = solver.translation_elements(
        prev, curr, R, pp, cp, cfg.association.min_line_verticality,
        np.radians(ocfg.translation_min_angle_deg),
    )  # fmt: skip
    heights = solver.height_elements(prev, curr, ij, np.radians(ocfg.z_plane_max_tilt_deg))
    tr, measured = solver._elements_translation(prev, curr, elems, heights, method, bounds, cfg)
    return elems.pairs, tr, measured


def _same(a: Any, b: Any) -> bool:
    """Equal to the last bit: arrays by dtype, shape and bytes, floats by their bits."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    if isinstance(a, float) or isinstance(b, float):
        return bool(np.float64(a).tobytes() == np.float64(b).tobytes())
    return bool(a == b)


def _assert_same(fused: tuple, numpy: tuple) -> None:
    assert _same(fused[0], numpy[0]) and fused[2] == numpy[2]
    tr_f, tr_n = fused[1], numpy[1]
    assert (tr_f is None) == (tr_n is None)
    if tr_f is None:
        return
    for name in ("txy", "z", "cov", "sigma_z", "z_observed", "best", "height"):
        assert _same(getattr(tr_f, name), getattr(tr_n, name)), name
    c_f, c_n = tr_f.consensus, tr_n.consensus
    for name in ("best_index", "best_candidate", "errors", "element_errors", "inliers"):
        assert _same(getattr(c_f, name), getattr(c_n, name)), name


def _captured(monkeypatch: pytest.MonkeyPatch, solve: Any) -> list[tuple]:
    """The arguments of every consensus translation ``solve()`` makes."""
    seen: list[tuple] = []

    def spy(*args: Any) -> Any:
        seen.append(args[:9])  # not the parts the solver computed (or reused) for it
        return None  # the numpy path answers the solve itself

    monkeypatch.setattr(solver, "fused_translation", spy)
    solve()
    monkeypatch.undo()
    return seen


def _synthetic_solves(monkeypatch: pytest.MonkeyPatch, seed: int, pipeline: str) -> list[tuple]:
    rng = np.random.default_rng(seed)
    world = world_planes(rng, int(rng.integers(3, 10)), ground=bool(seed % 3))
    T = random_motion(rng, tz=float(rng.normal(0.0, 0.05)))
    prev, curr = observed_pair(world, T, rng, covariances=bool(seed % 2))
    cfg = PlanodomConfig().updated({"odometry.pipeline": pipeline}, source="test")
    prior = T if seed % 4 == 0 else None
    solve = lambda: solver.estimate_relative_pose(prev, curr, cfg, prior=prior)  # noqa: E731
    return _captured(monkeypatch, solve)


@pytest.mark.parametrize("pipeline", ["wocsc", "ocsc"])
def test_fused_gives_the_numpy_paths_bits_on_synthetic_solves(monkeypatch, pipeline):
    solves = 0
    for seed in range(40):
        for args in _synthetic_solves(monkeypatch, seed, pipeline):
            fused = fused_translation(*args)
            assert fused is not None  # plain arrays: the compiled path serves every solve
            _assert_same(fused, _numpy_path(args))
            solves += 1
    assert solves >= 40


def test_fused_gives_the_numpy_paths_bits_on_a_simulated_run(monkeypatch):
    from planodom.experiments.generalisation import declared_sweep, world_for
    from planodom.odometry import run_odometry
    from planodom.simulation.random_world import simulate_world, world_fields

    world = world_for(162)
    run = world_fields(world, simulate_world(world, 0.02, n_epochs=12, all_fields=True))
    cfg = declared_sweep(world, PlanodomConfig())
    solves = _captured(monkeypatch, lambda: run_odometry(run, cfg))
    assert len(solves) >= 12
    z_solved = 0
    for args in solves:
        fused = fused_translation(*args)
        assert fused is not None
        _assert_same(fused, _numpy_path(args))
        z_solved += fused[1] is not None and fused[1].z_observed
    assert z_solved >= 6  # the ground's height consensus ran


def test_cases_left_to_numpy(monkeypatch):
    args = next(a for a in _synthetic_solves(monkeypatch, 5, "wocsc") if len(a[3]) > 1)
    prev, curr, R, pp, cp, ij, method, bounds, cfg = args
    strided = replace(prev, offsets=np.repeat(prev.offsets, 2)[::2])
    assert fused_translation(strided, curr, R, pp, cp, ij, method, bounds, cfg) is None
    assert (
        fused_translation(prev, curr, R, pp.astype(np.int32), cp, ij, method, bounds, cfg) is None
    )
    bad = replace(prev, weights=-prev.weights)  # numpy's consensus raises on these
    assert fused_translation(bad, curr, R, pp, cp, ij, method, bounds, cfg) is None
    monkeypatch.setattr(fused_module, "_BUDGET", 0)  # the consensus's shortlist applies
    monkeypatch.setattr(fused_module, "_SHORTLIST", 0)
    assert fused_translation(*args) is None


@pytest.mark.parametrize("n", [*range(0, 40), 63, 64, 65, 100, 127, 128])
def test_pairwise_sum_is_numpys(n):
    rng = np.random.default_rng(n)
    for scale in (1e-6, 1.0, 1e6):
        a = rng.random(n) * scale * 10.0 ** rng.uniform(-3, 3, n)
        assert _same(_pairwise_sum(a), float(a.sum()))
    assert np.isnan(_pairwise_sum(np.ones(129)))  # longer sums are left to numpy


@pytest.mark.parametrize("m", [0, 1, 2, 3, 7, 8, 9, 16, 17, 40, 128])
def test_spread_is_the_solvers_einsum(m):
    rng = np.random.default_rng(m)
    for _ in range(20):
        d = rng.normal(size=(m, 2)) * 10.0 ** rng.uniform(-4, 1)
        w = rng.random(m) * 10.0 ** rng.uniform(-6, 2, m)
        with np.errstate(invalid="ignore"):
            expected = solver._spread(d, w)
        assert _same(_spread_kernel(d, w), expected)


def test_parts_do_not_read_the_bounds_centre_or_reach(monkeypatch):
    """:func:`fused_parts` under one pass's bounds, finished (``bounded``) under another's
    with the same ``z_prior``, gives the bits of :func:`fused_translation` under that
    other's: the solve without the prior reuses them (SPEED2D15)."""
    from planodom.odometry.fused_translation import bounded, fused_parts

    checked = 0
    for seed in range(40):
        for args in _synthetic_solves(monkeypatch, seed, "wocsc"):
            prev, curr, R, pp, cp, ij, method, bounds, cfg = args
            parts = fused_parts(prev, curr, R, pp, cp, ij, method, float(bounds.z_prior), cfg)
            rng = np.random.default_rng(seed)
            for t0, reach in ((bounds.t0, bounds.translation), (np.zeros(3), 2.0),
                              (rng.normal(0.0, 0.5, 3), 0.05)):  # fmt: skip
                other = bounds._replace(t0=t0, translation=reach)
                want = fused_translation(prev, curr, R, pp, cp, ij, method, other, cfg)
                got = bounded(parts, other, cfg)
                assert (got is None) == (want is None)
                if want is not None:
                    _assert_same(got, want)
                    checked += 1
    assert checked >= 100
