"""SDA in one compiled call gives the three calls' pairs (costs, scipy, gate).

Every SDA call of seeded synthetic solves and of a short simulated 2D-rig run is captured
(its kernel arguments) and answered twice: by :func:`planodom.sda_kernel.sda_kernel` (the
ported assignment inside the kernel) and by
:func:`planodom.association.scipy_strict_pairs` (the costs, scipy's
``linear_sum_assignment`` itself and the gate). Their pairs must be equal, bytes and dtype.
SDA's costs are full of ties (every forbidden match costs 1e6): a port that broke ties
otherwise than scipy would pick other pairs and fail here.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from planes_factory import observe, observed_pair, random_motion, world_planes

import planodom.association as association
from planodom.config import PlanodomConfig
from planodom.lsap import INVALID, SOLVED
from planodom.odometry import refine_loop, solver
from planodom.planes import PlaneSet
from planodom.sda_kernel import sda_kernel


def _captured(monkeypatch: pytest.MonkeyPatch, solve: Any) -> list[tuple]:
    """The kernel arguments of every SDA call ``solve()`` makes (the refinement's by its
    calls: its compiled call runs SDA inside, where no spy sees it)."""
    seen: list[tuple] = []
    kernel = association.sda_kernel

    def spy(*args: Any) -> Any:
        seen.append(args)
        return kernel(*args)

    monkeypatch.setattr(association, "sda_kernel", spy)
    monkeypatch.setattr(refine_loop, "compiled_refine", lambda *args: None)
    solve()
    monkeypatch.undo()
    return seen


def _assert_same_pairs(args: tuple) -> None:
    status, got = sda_kernel(*args)
    want = association.scipy_strict_pairs(*args)
    assert status == SOLVED
    assert got.dtype == want.dtype and got.shape == want.shape and got.flags.c_contiguous
    np.testing.assert_array_equal(got, want)


def test_sda_gives_scipys_pairs_on_synthetic_solves(monkeypatch: pytest.MonkeyPatch) -> None:
    calls = forbidden = 0
    for seed in range(40):
        rng = np.random.default_rng(seed)
        world = world_planes(rng, int(rng.integers(2, 10)), ground=bool(seed % 3))
        T = random_motion(rng, max_angle_deg=10.0, max_xy=1.0)
        prev, curr = observed_pair(world, T, rng)
        # drop some current planes: rectangular costs, both ways across the seeds
        curr = curr.take(np.flatnonzero(rng.random(len(curr)) < 0.7))
        if seed % 2:
            prev, curr = curr, prev
        cfg = PlanodomConfig()
        for args in _captured(
            monkeypatch,
            lambda: solver.estimate_relative_pose(prev, curr, cfg),  # noqa: B023
        ):
            _assert_same_pairs(args)
            ok, _ = association._strict_costs(*args)
            forbidden += int((~ok).sum() > 1)
            calls += 1
    assert calls >= 80 and forbidden >= 40  # ties among forbidden matches were exercised


def test_sda_gives_scipys_pairs_on_a_simulated_run(monkeypatch: pytest.MonkeyPatch) -> None:
    from planodom.experiments.generalisation import declared_sweep, world_for
    from planodom.odometry import run_odometry
    from planodom.simulation.random_world import simulate_world, world_fields

    world = world_for(162)
    run = world_fields(world, simulate_world(world, 0.02, n_epochs=12, all_fields=True))
    calls = _captured(
        monkeypatch, lambda: run_odometry(run, declared_sweep(world, PlanodomConfig()))
    )
    assert len(calls) >= 36
    for args in calls:
        _assert_same_pairs(args)


def _far_plane(seed: int) -> PlaneSet:
    """Planes of a seeded world, the first one's offset infinite."""
    planes = PlaneSet.from_planes(observe(world_planes(np.random.default_rng(seed), 5), np.eye(4)))
    offsets = planes.offsets.copy()
    offsets[0] = np.inf
    return replace(planes, offsets=offsets)


def test_costs_scipy_rejects_raise_scipys_error() -> None:
    """Costs scipy rejects (NaN: an infinite offset within an infinite offset bound makes
    its offset term inf / inf) give no pairs from the kernel, and the three calls raise
    scipy's own error. SDA's bounds are finite in a run, so this path is a guard."""
    far, planes = _far_plane(3), _far_plane(3)
    planes = replace(planes, offsets=np.where(np.isinf(planes.offsets), 1.0, planes.offsets))
    args = (
        far.normals, far.offsets, far.centroids, far.radii,
        planes.normals, planes.offsets, planes.centroids, planes.radii,
        np.eye(3), np.zeros(3), 0.99, np.inf, np.inf,
    )  # fmt: skip
    status, pairs = sda_kernel(*args)
    assert status == INVALID and pairs.shape == (0, 2)
    with pytest.raises(ValueError, match="invalid numeric entries"):
        association.scipy_strict_pairs(*args)


def test_sda_raises_where_scipy_raised() -> None:
    """Through :func:`planodom.association.strict_association`: the same costs (an
    infinite translation bound) raise scipy's error, as before the kernel."""
    far, planes = _far_plane(4), _far_plane(4)
    planes = replace(planes, offsets=np.where(np.isinf(planes.offsets), 1.0, planes.offsets))
    with pytest.raises(ValueError, match="invalid numeric entries"):
        association.strict_association(far, planes, np.eye(3), translation_bound=np.inf)
