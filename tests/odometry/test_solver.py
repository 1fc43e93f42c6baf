"""Tests of planodom.odometry.solver: the prior-free retry's status (``odometry.retry_accepts``)."""

from __future__ import annotations

import numpy as np

from planodom.config import PlanodomConfig
from planodom.odometry import Status, estimate_relative_pose
from planodom.odometry.solver import config_for_gap
from planodom.planes import PlaneSet
from tests.odometry.test_refine import _ground, _wall
from tests.planes_factory import observe


def _yaw_deg(T: np.ndarray) -> float:
    return float(np.degrees(np.arctan2(T[1, 0], T[0, 0])))


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
    c, s = np.cos(np.radians(3.0)), np.sin(np.radians(3.0))
    T_true = np.array([[c, -s, 0, 0.3], [s, c, 0, 0.05], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    prev = PlaneSet.from_planes(observe(world, np.eye(4)))
    curr = PlaneSet.from_planes(observe(world, T_true))
    c, s = np.cos(np.radians(33.0)), np.sin(np.radians(33.0))
    prior = np.array([[c, -s, 0, 0.3], [s, c, 0, 0.05], [0, 0, 1, 0], [0, 0, 0, 1.0]])
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
    c, s = np.cos(np.radians(3.0)), np.sin(np.radians(3.0))
    T_true = np.array([[c, -s, 0, 0.3], [s, c, 0, 0.05], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    prev = PlaneSet.from_planes(observe(world, np.eye(4)))
    curr = PlaneSet.from_planes(observe(world, T_true))
    c, s = np.cos(np.radians(33.0)), np.sin(np.radians(33.0))
    prior = np.array([[c, -s, 0, 0.3], [s, c, 0, 0.05], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    for value, gap, status in (("across_gap", 1, Status.DEGENERATE),
                               ("across_gap", 2, Status.UNRESOLVED),
                               ("ok", 1, Status.UNRESOLVED)):  # fmt: skip
        cfg = base.updated({"odometry.retry_accepts": value}, source="test")
        r = estimate_relative_pose(prev, curr, config_for_gap(cfg, 2), prior, 0.02,
                                   step=True, gap=gap)  # fmt: skip
        assert r.status is status
        if status is Status.DEGENERATE:
            np.testing.assert_allclose(r.T_prev_curr[:3, :3], T_true[:3, :3], atol=1e-8)
