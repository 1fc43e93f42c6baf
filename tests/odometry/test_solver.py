"""Tests of planodom.odometry.solver. The prior-free retry's status (``odometry.retry_accepts``);
and the solve without the prior reuses the first solve's rotation and translation parts,
and ends once it cannot win, only where that changes no bit
(:func:`planodom.odometry.solver._rotated`, ``_measured_translation``, ``_solve``'s
``beat``).

Every relative pose of seeded synthetic epochs (degenerate ones among them: two walls
and the ground) and of a short simulated 2D-rig run at 2 cm is computed twice: as the
solver does it, and with nothing reused (``held`` None: the rotation and the
translation pairs and the compiled translation's parts computed again by the retry, and
a retry that cannot win finished: the solver before SPEED2D15). The results
must be equal to the last bit, and the reuse and the early end must have served retries
in both.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from planes_factory import observed_pair, random_motion, world_planes

import planodom.odometry.solver as solver
from planodom.association import PairAssociations, lenient_association
from planodom.config import PlanodomConfig
from planodom.geometry import make_transform
from planodom.odometry import Status, estimate_relative_pose
from planodom.odometry.solver import config_for_gap
from planodom.planes import PlaneSet
from tests.odometry.test_fused_translation import _same
from tests.odometry.test_refine import _ground, _wall
from tests.planes_factory import observe


def _assert_same(got: Any, want: Any) -> None:
    for name in ("T_prev_curr", "covariance", "status", "associations", "z_observed",
                 "sigma_z", "sources"):  # fmt: skip
        assert _same(getattr(got, name), getattr(want, name)), name
    g, w = got.diagnostics, want.diagnostics
    for name in ("rotation_pair", "translation_pair", "n_translation_pairs", "used_prior"):
        assert _same(getattr(g, name), getattr(w, name)), name
    for name in ("prev_pairs", "curr_pairs", "rotations", "weights"):
        assert _same(getattr(g.lda, name), getattr(w.lda, name)), name


def _counted(monkeypatch: pytest.MonkeyPatch) -> dict[str, int]:
    """Counts of the retries that reused the rotation (``_rotated`` answering from
    ``held`` without calling ``_rotation``)."""
    n = {"rotated": 0, "computed": 0, "parts": 0, "ended": 0}
    rotated, rotation, parts = solver._rotated, solver._rotation, solver.fused_parts
    solve = solver._solve

    def spy_solve(*args: Any) -> Any:
        out = solve(*args)
        n["ended"] += out is None
        return out

    def spy_parts(*args: Any) -> Any:
        n["parts"] += 1
        return parts(*args)

    def spy_rotated(*args: Any) -> Any:
        n["rotated"] += 1
        return rotated(*args)

    def spy_rotation(*args: Any) -> Any:
        n["computed"] += 1
        return rotation(*args)

    monkeypatch.setattr(solver, "_rotated", spy_rotated)
    monkeypatch.setattr(solver, "_rotation", spy_rotation)
    monkeypatch.setattr(solver, "fused_parts", spy_parts)
    monkeypatch.setattr(solver, "_solve", spy_solve)
    return n


def _without_reuse(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every solve as before SPEED2D15: nothing held, no rank to beat."""
    solve = solver._solve
    monkeypatch.setattr(solver, "_solve", lambda *a: solve(*a[:7]))


def _synthetic(seed: int) -> tuple:
    rng = np.random.default_rng(seed)
    world = world_planes(rng, 2 if seed % 2 else int(rng.integers(3, 8)), ground=True)
    T = random_motion(rng, tz=float(rng.normal(0.0, 0.05)))
    prev, curr = observed_pair(world, T, rng, covariances=bool(seed % 3))
    off = make_transform(np.eye(3), rng.normal(0.0, 0.3, 3))  # a prior off by decimetres
    return prev, curr, T @ off


@pytest.mark.parametrize("pipeline", ["wocsc", "ocsc", "sda-mean"])
def test_reuse_gives_the_bits_of_the_solve_again_on_synthetic_epochs(monkeypatch, pipeline):
    cfg = PlanodomConfig().updated({"odometry.pipeline": pipeline}, source="test")
    cases = [_synthetic(seed) for seed in range(60)]
    n = _counted(monkeypatch)
    got = [solver.estimate_relative_pose(p, c, cfg, prior=T, step=True) for p, c, T in cases]
    monkeypatch.undo()
    _without_reuse(monkeypatch)
    want = [solver.estimate_relative_pose(p, c, cfg, prior=T, step=True) for p, c, T in cases]
    for g, w in zip(got, want, strict=True):
        _assert_same(g, w)
    reused = n["rotated"] - n["computed"]
    assert reused >= 5 if pipeline != "sda-mean" else reused == 0  # "cog": never reused
    assert n["parts"] <= n["rotated"] - reused  # the translation's parts with them
    assert n["ended"] >= 5  # retries that could not win, ended at their status


def test_reuse_gives_the_bits_of_the_solve_again_on_a_simulated_run(monkeypatch):
    from planodom.experiments.generalisation import declared_sweep, world_for
    from planodom.odometry import run_odometry
    from planodom.simulation.random_world import simulate_world, world_fields

    world = world_for(426)  # degenerate in most steps at 2 cm: the retry runs
    run = world_fields(world, simulate_world(world, 0.02, n_epochs=15, all_fields=True))
    cfg = declared_sweep(world, PlanodomConfig())
    n = _counted(monkeypatch)
    got = run_odometry(run, cfg)
    monkeypatch.undo()
    _without_reuse(monkeypatch)
    want = run_odometry(run, cfg)
    assert _same(np.asarray(got.poses), np.asarray(want.poses))
    assert got.statuses == want.statuses
    assert n["rotated"] - n["computed"] >= 5
    assert n["parts"] == n["computed"]  # every solve reaching them: none computed again
    assert n["ended"] >= 5


def test_rotated_reuses_only_the_same_bytes():
    prev, curr, T = _synthetic(4)
    cfg, methods = PlanodomConfig(), ("wocsc", "wocsc")
    lda = solver.lenient_association(prev, curr, cfg.association, None)
    assert len(lda) > 1
    bounds = solver.pass_bounds(cfg, T, False, None)
    held: list = []
    first = solver._rotated(prev, curr, lda, methods, bounds, cfg, held)
    assert held[0] is lda and held[1] is first
    copied = PairAssociations(lda.prev_pairs.copy(), lda.curr_pairs.copy(),
                              lda.rotations.copy(), lda.weights.copy())  # fmt: skip
    assert solver._rotated(prev, curr, copied, methods, bounds, cfg, held) is first
    nudged = lda.weights.copy()
    nudged[0] = np.nextafter(nudged[0], 2.0)  # one ulp
    for other in (
        PairAssociations(
            lda.prev_pairs[1:], lda.curr_pairs[1:], lda.rotations[1:], lda.weights[1:]
        ),  # fmt: skip
        PairAssociations(lda.prev_pairs, lda.curr_pairs, lda.rotations, nudged),
    ):
        out = solver._rotated(prev, curr, other, methods, bounds, cfg, held)
        assert out is not first and held[0] is other  # computed again, and held
        fresh = solver._rotated(prev, curr, other, methods, bounds, cfg, None)
        for a, b in zip(out[:2] + out[3:], fresh[:2] + fresh[3:], strict=True):
            assert _same(a, b)


def _yaw_deg(T: np.ndarray) -> float:
    return float(np.degrees(np.arctan2(T[1, 0], T[0, 0])))


def _yawed(yaw_deg: float) -> np.ndarray:
    """(4, 4) a yaw of ``yaw_deg`` and a step of (0.3, 0.05) m."""
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    return np.array([[c, -s, 0, 0.3], [s, c, 0, 0.05], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _turned(world: list) -> tuple:
    """``world`` seen from the identity and after a 3 deg turn, and a prior 30 deg off
    the truth: (prev, curr, T_true, prior)."""
    T_true = _yawed(3.0)
    prev = PlaneSet.from_planes(observe(world, np.eye(4)))
    return prev, PlaneSet.from_planes(observe(world, T_true)), T_true, _yawed(33.0)


def _ambiguous_step():
    """A vehicle standing still (the truth: identity) whose reference holds the ground and
    one wall, and whose current epoch the ground and another wall at 90 deg to it (the
    first out of sight): the two pairs share their dihedral angle, so without bounds the
    pair gives a 90 deg yaw; under the prior (the truth) the walls do not associate."""
    ground, wall_a, wall_b = _ground(0), _wall(0.0, 8.0, 0.0, 1), _wall(np.pi / 2, 6.0, 0.0, 2)
    prev = PlaneSet.from_planes(observe([ground, wall_a], np.eye(4)))
    curr = PlaneSet.from_planes(observe([ground, wall_b], np.eye(4)))
    return prev, curr


def test_prior_free_degenerate_retry_kept_with_degenerate_is_the_dihedral_alias():
    """``retry_accepts: degenerate`` keeps the retry's degenerate step: its yaw is the
    alias, 90 deg off the truth (the failure ``ok`` is for)."""
    prev, curr = _ambiguous_step()
    base = PlanodomConfig().updated({"odometry.retry_accepts": "degenerate"}, source="test")
    cfg = config_for_gap(base, 12)  # bounds of a 12-epoch gap: 180 deg
    r = estimate_relative_pose(prev, curr, cfg, np.eye(4), 0.02, step=True)
    assert r.status is Status.DEGENERATE
    assert abs(abs(_yaw_deg(r.T_prev_curr)) - 90.0) < 1e-6


def test_retry_accepts_ok_leaves_the_step_unresolved_on_the_prior():
    """With ``retry_accepts: ok`` (the default) the degenerate alias is not kept: the step
    is unresolved and its pose is the prior's (here the truth)."""
    prev, curr = _ambiguous_step()
    base = PlanodomConfig()
    assert base.odometry.retry_accepts == "ok"
    r = estimate_relative_pose(prev, curr, config_for_gap(base, 12), np.eye(4), 0.02, step=True)
    assert r.status is Status.UNRESOLVED
    np.testing.assert_allclose(r.T_prev_curr, np.eye(4), atol=1e-12)


def test_retry_accepts_ok_keeps_an_ok_retry():
    """A prior 30 deg off the truth on a fully measured step (ground and two walls at 70
    deg): under the prior's bounds nothing associates, the prior-free retry is OK and is
    kept with either value, equal to the truth."""
    world = [_ground(0), _wall(0.4, 8.0, 0.0, 1), _wall(0.4 + np.radians(70), 6.0, 1.0, 2)]
    prev, curr, T_true, prior = _turned(world)
    for value in ("degenerate", "ok"):
        cfg = config_for_gap(PlanodomConfig().updated({"odometry.retry_accepts": value},
                                                      source="test"), 3)  # fmt: skip
        r = estimate_relative_pose(prev, curr, cfg, prior, 0.02, step=True)
        assert r.status is Status.OK
        np.testing.assert_allclose(r.T_prev_curr, T_true, atol=1e-8)


def test_retry_accepts_across_gap():
    """``across_gap`` drops the alias across a 12-epoch gap (as ``ok``) and keeps a
    degenerate retry over one epoch (as the default): a corridor (the ground and two
    parallel walls; the step along it unmeasured) under a prior 30 deg off, whose
    rotation is then the truth's."""
    prev, curr = _ambiguous_step()
    base = PlanodomConfig().updated({"odometry.retry_accepts": "across_gap"}, source="test")
    r = estimate_relative_pose(prev, curr, config_for_gap(base, 12), np.eye(4), 0.02,
                               step=True, gap=12)  # fmt: skip
    assert r.status is Status.UNRESOLVED
    world = [_ground(0), _wall(0.0, 3.0, 0.0, 1), _wall(np.pi, 2.5, 0.0, 2)]
    prev, curr, T_true, prior = _turned(world)
    for value, gap, status in (("across_gap", 1, Status.DEGENERATE),
                               ("across_gap", 2, Status.UNRESOLVED),
                               ("ok", 1, Status.UNRESOLVED)):  # fmt: skip
        cfg = base.updated({"odometry.retry_accepts": value}, source="test")
        r = estimate_relative_pose(prev, curr, config_for_gap(cfg, 2), prior, 0.02,
                                   step=True, gap=gap)  # fmt: skip
        assert r.status is status
        if status is Status.DEGENERATE:
            np.testing.assert_allclose(r.T_prev_curr[:3, :3], T_true[:3, :3], atol=1e-8)


def test_retry_accepts_is_the_streaming_steps_only():
    """A pair that is not a streaming step (the smoothing's pairs, loop candidates, map
    matches) keeps a degenerate retry under the default ``ok``: the alias comes back."""
    prev, curr = _ambiguous_step()
    cfg = config_for_gap(PlanodomConfig(), 12)
    r = estimate_relative_pose(prev, curr, cfg, np.eye(4), 0.02)
    assert r.status is Status.DEGENERATE
    assert abs(abs(_yaw_deg(r.T_prev_curr)) - 90.0) < 1e-6


def test_gap_tilt_held_keeps_one_epochs_tilt_bound():
    """``gap_tilt: held``: a 12-epoch gap widens the rotation bound to 180 deg and keeps
    the tilt bound at one epoch's 20 deg; ``widened`` leaves it unbounded; a one-epoch
    step is the config itself."""
    held = PlanodomConfig().updated({"odometry.gap_tilt": "held"}, source="test")
    assert config_for_gap(held, 1) is held
    a = config_for_gap(held, 12).association
    assert (a.max_rotation_deg, a.max_tilt_deg) == (180.0, 20.0)
    a = config_for_gap(PlanodomConfig(), 12).association
    assert (a.max_rotation_deg, a.max_tilt_deg) == (180.0, 180.0)


def test_gap_tilt_held_drops_a_tilted_alias_across_a_gap():
    """Across a 12-epoch gap the prior-free association may pair the reference's ground
    and wall with the current wall and ground (same dihedral angle): a 90 deg tilt. With
    ``widened`` LDA offers it; with ``held`` every candidate keeps the base z axis within
    one epoch's bound plus the normal tolerance (each rotation checked on its matrix)."""
    ground, wall_a = _ground(0), _wall(0.0, 8.0, 0.0, 1)
    wall_b = _wall(np.pi / 2, 6.0, 0.0, 2)
    prev = PlaneSet.from_planes(observe([ground, wall_a], np.eye(4)))
    curr = PlaneSet.from_planes(observe([ground, wall_b], np.eye(4)))
    tilts = {}
    for value in ("widened", "held"):
        cfg = config_for_gap(PlanodomConfig().updated({"odometry.gap_tilt": value},
                                                      source="test"), 12)  # fmt: skip
        lda = lenient_association(prev, curr, cfg.association)
        tilts[value] = [np.degrees(np.arccos(np.clip(R[2, 2], -1, 1))) for R in lda.rotations]
    assert max(tilts["widened"]) > 80.0
    assert tilts["held"] and max(tilts["held"]) <= 25.0
