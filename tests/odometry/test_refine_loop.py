"""The refinement in one compiled call gives the calls' bits.

Every refinement of seeded synthetic solves and of short simulated 2D-rig runs is
captured at the solver and answered twice: by
:func:`planodom.odometry.refine_loop.compiled_refine` (one kernel: both SDA rounds with
the ported assignment, the fits, the reach test) and by
:func:`planodom.odometry.refine_loop.called_refine` (SDA with scipy's assignment, the
fits, Python between them). Their results must be equal to the last bit (every array's
bytes and dtype, every scalar); a kernel that changed an operation's order, a bound or a
branch (the degenerate fit from the prediction, the reach test) fails here.
"""

from __future__ import annotations

from dataclasses import replace
from functools import partial
from typing import Any

import numpy as np
import pytest
from planes_factory import (
    observed_pair,
    random_motion,
    world_planes,
)

import planodom.odometry.solver as solver
from planodom.config import PlanodomConfig
from planodom.odometry import refine_loop
from planodom.odometry.refine_loop import called_refine, compiled_refine
from planodom.planes import PlaneSet


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    return type(a) is type(b) and (a == b or (a != a and b != b))


def _assert_same(got: refine_loop.Refined, want: refine_loop.Refined) -> None:
    assert got.R is want.R
    for name in ("t", "cov_xy", "sigma_z", "z_observed", "measured", "n_planes"):
        assert _same(getattr(got.fit, name), getattr(want.fit, name)), name


def _captured(monkeypatch: pytest.MonkeyPatch, solve: Any) -> list[tuple]:
    """The arguments of every refinement ``solve()`` makes."""
    seen: list[tuple] = []

    def spy(*args: Any) -> Any:
        seen.append(args)
        return called_refine(*args)

    monkeypatch.setattr(solver, "refine", spy)
    solve()
    monkeypatch.undo()
    return seen


def _check(calls: list[tuple]) -> dict[str, int]:
    """Each call both ways; counts of the compiled calls and their degenerate fits."""
    n = {"compiled": 0, "degenerate": 0, "unmeasured": 0}
    for args in calls:
        got, want = compiled_refine(*args), called_refine(*args)
        assert got is not None
        _assert_same(got, want)
        n["compiled"] += 1
        n["unmeasured"] += not want.fit.measured
        n["degenerate"] += not args[4]
    return n


@pytest.mark.parametrize("unmeasured", ["prediction", "prior", "kept", "walls"])
def test_compiled_gives_the_calls_bits_on_synthetic_solves(monkeypatch, unmeasured):
    total = 0
    for seed in range(30):
        rng = np.random.default_rng(seed)
        world = world_planes(rng, int(rng.integers(1, 8)), ground=bool(seed % 3))
        T = random_motion(rng, tz=float(rng.normal(0.0, 0.05)))
        prev, curr = observed_pair(world, T, rng, covariances=bool(seed % 2))
        cfg = PlanodomConfig().updated(
            {"odometry.refine_unmeasured": unmeasured, "odometry.estimate_z": seed % 5 != 0},
            source="test",
        )
        prior = T if seed % 4 else None
        sigma = 0.05 if seed % 3 else None
        solve = partial(solver.estimate_relative_pose, prev, curr, cfg, prior, sigma)
        total += _check(_captured(monkeypatch, solve))["compiled"]
    assert total >= 30


@pytest.mark.parametrize(("world_id", "noise"), [(162, 0.02), (160, 0.006), (164, 0.02)])
def test_compiled_gives_the_calls_bits_on_a_simulated_run(monkeypatch, world_id, noise):
    from planodom.experiments.generalisation import declared_sweep, world_for
    from planodom.odometry import run_odometry
    from planodom.simulation.random_world import simulate_world, world_fields

    world = world_for(world_id)
    run = world_fields(world, simulate_world(world, noise, n_epochs=12, all_fields=True))
    cfg = declared_sweep(world, PlanodomConfig())
    n = _check(_captured(monkeypatch, lambda: run_odometry(run, cfg)))
    assert n["compiled"] >= 12


def _six_walls(monkeypatch) -> tuple[PlaneSet, PlaneSet, tuple]:
    """A seeded solve of six walls and a ground: its two plane sets and the refinement's
    captured arguments."""
    rng = np.random.default_rng(1)
    world = world_planes(rng, 6)
    T = random_motion(rng)
    prev, curr = observed_pair(world, T, rng)
    args = _captured(monkeypatch, lambda: solver.estimate_relative_pose(prev, curr))[0]
    return prev, curr, args


def test_cases_left_to_the_calls(monkeypatch) -> None:
    prev, curr, args = _six_walls(monkeypatch)
    assert compiled_refine(*args) is not None
    pose = args[6].updated({"odometry.refinement": "pose"}, source="test")
    assert compiled_refine(*args[:6], pose, args[7]) is None
    assert compiled_refine(*args[:7], 0.1) is None  # the non-holonomic constraint
    frozen = replace(prev, normals=np.asfortranarray(prev.normals))
    assert compiled_refine(frozen, *args[1:]) is None


def test_the_reach_test_and_no_associations(monkeypatch) -> None:
    """A fit beyond the reach keeps the initial translation (both ways); at the reach,
    within 1e-9 of it, the calls decide; planes SDA cannot associate give the fit of no
    associations (the initial translation, the prior's covariance)."""
    prev, curr, args = _six_walls(monkeypatch)
    fit = called_refine(*args).fit
    assert fit.measured and fit.n_planes >= 4
    norm = float(np.hypot(*(fit.t[:2] - args[5].t0[:2])))
    tol = args[6].association.offset_tol_m
    undecided = 0
    for scale in (0.5, 1.0 - 1e-12, 1.0, 1.0 + 1e-12, 2.0):
        bounds = args[5]._replace(translation=scale * norm - tol)
        want = called_refine(*args[:5], bounds, *args[6:])
        got = compiled_refine(*args[:5], bounds, *args[6:])
        if got is None:
            undecided += 1
            continue
        _assert_same(got, want)
        if scale == 0.5:  # beyond the reach: the initial translation, not a measurement
            assert want.fit.n_planes == 0 and not want.fit.measured
            assert np.array_equal(want.fit.t, args[3])
    assert undecided <= 3
    far = replace(curr, offsets=curr.offsets + 100.0)
    got, want = compiled_refine(prev, far, *args[2:]), called_refine(prev, far, *args[2:])
    assert got is not None and want.fit.n_planes == 0
    _assert_same(got, want)
