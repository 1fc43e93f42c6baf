"""The non-holonomic constraint of a degenerate step (planodom.odometry.nonholonomic)."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.geometry import se3_exp
from planodom.odometry import Status, estimate_relative_pose
from planodom.odometry.nonholonomic import lateral_row, lateral_sigma
from planodom.odometry.refine import plane_translation
from planodom.planes import PlaneSet
from tests.odometry.test_refine import _ground, _wall
from tests.planes_factory import observe


def test_level_arc_closed_form():
    """A level arc turning by theta: t = r (sin theta, 1 - cos theta), so the row is
    (-tan(theta / 2), 1, 0) normalised."""
    for theta in (1e-8, 0.05, 0.4, -0.9):
        c = se3_exp(np.array([0.0, 0.0, theta, 0.0, 0.0, 0.0]))[:3, :3]
        expected = np.array([-np.tan(theta / 2), 1.0, 0.0])
        np.testing.assert_allclose(lateral_row(c), expected / np.linalg.norm(expected),
                                   atol=1e-12)  # fmt: skip


def test_steps_without_lateral_velocity_satisfy_it_others_do_not():
    rng = np.random.default_rng(7)
    for _ in range(50):
        w = rng.normal(0.0, [0.05, 0.05, 0.5])
        vx, vz, vy = rng.uniform(0.5, 3.0), rng.normal(0.0, 0.1), rng.uniform(0.05, 0.5)
        T = se3_exp(np.r_[w, vx, 0.0, vz])
        assert abs(lateral_row(T[:3, :3]) @ T[:3, 3]) < 1e-12
        S = se3_exp(np.r_[w, vx, vy, vz])
        assert abs(lateral_row(S[:3, :3]) @ S[:3, 3]) > 0.5 * vy


def _oblique_wall(dt: float = 0.2):
    """Ground and one wall whose normal has azimuth 0.4 rad + 180 deg (its along-wall
    direction mostly lateral); the true step a car's arc: 1.5 m/s, 20 deg/s, no lateral
    velocity, a little pitch and heave."""
    world = [_ground(0), _wall(0.4, 8.0, 0.0, 1)]
    T_true = se3_exp(np.array([0.0, 0.02, np.radians(20.0), 1.5, 0.0, 0.05]) * dt)
    prev, curr = observe(world, np.eye(4)), observe(world, T_true)
    along = np.array([-np.sin(0.4), np.cos(0.4)])
    return PlaneSet.from_planes(prev), PlaneSet.from_planes(curr), T_true, along


@pytest.mark.parametrize("mode", ["prediction", "prior"])
def test_degenerate_step_takes_the_unmeasured_direction_from_the_constraint(mode):
    p, c, T_true, along = _oblique_wall()
    ij = np.array([[0, 0], [1, 1]])
    t_true = T_true[:3, 3]
    pred = t_true + np.r_[0.15 * along, 0.0]  # the prediction 15 cm off along the wall
    R = T_true[:3, :3]
    args = (p, c, R, ij, pred, 0.9, 0.003, 0.03, 0.3**2)
    kw = {"unmeasured": mode, "prediction_var": 0.05**2, "predicted": pred}
    without = plane_translation(*args, **kw)
    fit = plane_translation(*args, **kw, lateral_sigma_m=0.005)
    assert not without.measured and not fit.measured  # still degenerate: the planes' word
    assert abs((without.t[:2] - t_true[:2]) @ along) > 0.1
    np.testing.assert_allclose(fit.t, t_true, atol=1e-6)  # noise-free planes, exact arc
    assert along @ fit.cov_xy @ along < 0.01**2


def test_through_the_solver_only_with_a_nonholonomic_model_and_for_a_step():
    """Only the streaming odometry's step (``step=True``) of a non-holonomic model: a
    loop's or a skip's pair of epochs is no step of one constant twist."""
    p, c, T_true, along = _oblique_wall()
    prior = T_true.copy()
    prior[:2, 3] += 0.08 * along
    base = PlanodomConfig()
    for model, exact in (("constant_velocity", False), ("nonholonomic", True),
                         ("nonholonomic_degenerate", True)):  # fmt: skip
        cfg = base.updated({"odometry.motion_model": model}, source="test")
        r = estimate_relative_pose(p, c, cfg, prior, prior_sigma_m=0.02, step=True)
        assert r.status is Status.DEGENERATE
        off = abs((r.T_prev_curr[:2, 3] - T_true[:2, 3]) @ along)
        assert (off < 1e-6) if exact else (off > 0.05)
        pair = estimate_relative_pose(p, c, cfg, prior, prior_sigma_m=0.02)
        assert abs((pair.T_prev_curr[:2, 3] - T_true[:2, 3]) @ along) > 0.05
    assert lateral_sigma(base.odometry) == 0.0


def test_a_measured_step_is_not_touched():
    """Two walls at 70 deg and the ground measure the step: a step with a lateral
    velocity (a base origin ahead of the rear axle) is recovered exactly, not pulled."""
    world = [_ground(0), _wall(0.4, 8.0, 0.0, 1), _wall(0.4 + np.radians(70), 6.0, 1.0, 2)]
    T_true = se3_exp(np.array([0.0, 0.0, 0.07, 0.3, 0.04, 0.0]))
    prev, curr = observe(world, np.eye(4)), observe(world, T_true)
    cfg = PlanodomConfig().updated({"odometry.motion_model": "nonholonomic"}, source="test")
    r = estimate_relative_pose(PlaneSet.from_planes(prev), PlaneSet.from_planes(curr), cfg,
                               step=True)  # fmt: skip
    assert r.status is Status.OK
    np.testing.assert_allclose(r.T_prev_curr, T_true, atol=1e-8)
