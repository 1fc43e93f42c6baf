"""``planemap.few_inliers: observed``: fewer than ``min_inliers`` planes that fix every
direction resolve an epoch, exactly; fewer that leave one free do not."""

from __future__ import annotations

import numpy as np
import pytest
from planemap_factory import plane_points, planes_of, pose

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError
from planodom.odometry import Status
from planodom.odometry.planemap import PlaneMapOdometry
from planodom.odometry.planemap.few_inliers import observed_few

T_TRUE = pose([0.3, -0.2, 2.0], [0.9, 0.05, 0.01])


def _room(T, end_wall=True, seed=3):
    """A corridor seen from pose ``T``: floor, ceiling, the two long walls, and an end
    wall (normal along the corridor) or, without it, a third long wall."""
    rng = np.random.default_rng(seed)
    inv = np.linalg.inv(T)
    sets = [
        plane_points(rng, [0, 0, 1.0], 1.8, [0, 0, -1.8], 16, 600),  # floor
        plane_points(rng, [0, 0, -1.0], 2.0, [0, 0, 2.0], 16, 600),  # ceiling
        plane_points(rng, [0, 1.0, 0], 2.3, [0, -2.3, 0], 16, 500),  # long walls
        plane_points(rng, [0, -1.0, 0], 2.3, [0, 2.3, 0], 16, 500),
    ]
    if end_wall:
        sets.append(plane_points(rng, [-1.0, 0, 0], 15.0, [15, 0, 0], 3, 150))
    else:  # a recess of the right wall: parallel, nothing along the corridor
        sets.append(plane_points(rng, [0, -1.0, 0], 3.1, [6, 3.1, 0], 3, 150))
    return planes_of([S @ inv[:3, :3].T + inv[:3, 3] for S in sets])


def _step(rule: str, end_wall: bool = True, floor: int = 4):
    cfg = PlanodomConfig().updated({
        "planemap.laser_bias_m": 0.0, "planemap.few_inliers": rule,
        "planemap.few_inliers_floor": floor,
    })  # fmt: skip
    odo = PlaneMapOdometry(cfg)
    odo.commit(odo.estimate(_room(np.eye(4), end_wall)))
    return odo.estimate(_room(T_TRUE, end_wall)).relative


def test_five_planes_that_fix_every_direction_give_the_true_step():
    """Five exact planes (normals along x, y and z) resolve the step to the truth with
    ``observed``; with the default the same epoch is unresolved and bridged (identity)."""
    rel = _step("observed")
    assert rel.status is Status.OK
    np.testing.assert_allclose(rel.T_prev_curr, T_TRUE, atol=1e-9)
    off = _step("unresolved")
    assert off.status is Status.UNRESOLVED
    np.testing.assert_allclose(off.T_prev_curr, np.eye(4), atol=1e-12)  # the prediction


def test_five_planes_that_leave_the_corridor_free_stay_unresolved():
    """Without a normal along the corridor, nothing fixes the translation along it: five
    planes are not trusted then, where a count of 4 (``min_inliers: 4``) would keep the
    epoch as degenerate."""
    assert _step("observed", end_wall=False).status is Status.UNRESOLVED
    cfg = PlanodomConfig().updated({"planemap.laser_bias_m": 0.0, "planemap.min_inliers": 4})
    odo = PlaneMapOdometry(cfg)
    odo.commit(odo.estimate(_room(np.eye(4), end_wall=False)))
    assert odo.estimate(_room(T_TRUE, end_wall=False)).relative.status is Status.DEGENERATE


def test_the_floor_bounds_the_count():
    """Five planes under a floor of six are left to ``min_inliers`` (unresolved)."""
    assert _step("observed", floor=6).status is Status.UNRESOLVED


def test_observed_few_against_the_covariance_in_closed_form():
    """The rule on a diagonal information: every direction's 1-sigma against its limit
    (1 deg, 0.1 m by default), through the motion bounds' weak prior."""
    cfg = PlanodomConfig().updated({"planemap.few_inliers": "observed"})
    info = np.r_[[1.0 / np.radians(0.5) ** 2] * 3, [1.0 / 0.05**2] * 3]
    assert observed_few(np.diag(info), 4, cfg)
    assert not observed_few(np.diag(info), 3, cfg)  # below the floor
    assert not observed_few(np.diag(info), 5, PlanodomConfig())  # off
    for axis, limit in ((1, np.radians(1.0)), (5, 0.1)):  # pitch, then the vertical
        weak = info.copy()
        weak[axis] = 1.0 / (1.2 * limit) ** 2  # 1-sigma 1.2x the limit (prior ~ nothing)
        assert not observed_few(np.diag(weak), 5, cfg)
        weak[axis] = 1.0 / (0.9 * limit) ** 2
        assert observed_few(np.diag(weak), 5, cfg)


def test_a_bad_value_names_the_field():
    with pytest.raises(ConfigError, match="few_inliers"):
        PlanodomConfig().updated({"planemap.few_inliers": "maybe"})
    with pytest.raises(ConfigError, match="few_inliers_floor"):
        PlanodomConfig().updated({"planemap.few_inliers_floor": 2})
