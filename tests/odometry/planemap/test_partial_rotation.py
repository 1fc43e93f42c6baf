"""An epoch whose planes fix only part of the rotation (the ground alone: roll and pitch,
not yaw): ``planemap.partial_rotation``, measured where observed, the prediction's about
the free axis, reported ``rotation_partly_observed`` (issue 11, recordings' robustness)."""

from __future__ import annotations

import numpy as np
import pytest
from planemap_factory import plane_points, planes_of, pose, scene_points

from planodom.config import PlanodomConfig
from planodom.geometry import rpy_from_rotation
from planodom.odometry import Status
from planodom.odometry.planemap import PlaneMapOdometry

#: True poses: 2 deg of yaw and 0.3 m an epoch, then an epoch that turns by 3 deg (the
#: prediction says 2) and rolls by 1 deg while only the ground is seen.
POSES = [pose([0, 0, 2 * k], [0.3 * k, 0, 0]) for k in range(3)]
POSES.append(POSES[-1] @ pose([1, 0, 3], [0.3, 0, 0]))


#: Horizontal planes only (one family): three ground patches and four flat roofs or
#: ceilings at other heights, (height, centre x, centre y).
FLAT = [(-1.8, -5, 0), (-1.8, 5, 2), (-1.8, 0, -5), (3.0, 4, 6), (4.0, -6, 5), (5.0, 6, -6),
        (3.5, -5, -6)]  # fmt: skip


def _scan(k: int) -> list:
    rng = np.random.default_rng(50 + k)
    inv = np.linalg.inv(POSES[k])
    sets = [plane_points(rng, [0, 0, 1.0], -h, [x, y, h], 5, 400) for h, x, y in FLAT]
    if k < 3:  # the scene's walls and slanted roofs too
        sets += scene_points(rng)[1:]
    return planes_of([S @ inv[:3, :3].T + inv[:3, 3] for S in sets])


def _last(mode: str):
    odo = PlaneMapOdometry(PlanodomConfig().updated({"planemap.partial_rotation": mode}))
    for k in range(3):
        odo.commit(odo.estimate(_scan(k)))
    sigma_pred = odo.sigmas()[0]
    return odo.estimate(_scan(3)).relative, sigma_pred


def test_ground_only_measures_roll_and_predicts_yaw() -> None:
    rel, sigma_pred = _last("prediction")
    assert rel.rotation_partly_observed and rel.status is Status.DEGENERATE
    roll, pitch, yaw = np.degrees(rpy_from_rotation(rel.T_prev_curr[:3, :3]))
    assert roll == pytest.approx(1.0, abs=0.02)  # measured by the ground
    assert pitch == pytest.approx(0.0, abs=0.02)
    assert yaw == pytest.approx(2.0, abs=0.02)  # the prediction's, not a measurement
    # the yaw's uncertainty is the prediction's, roll and pitch the ground's (small)
    assert np.sqrt(rel.covariance[2, 2]) == pytest.approx(sigma_pred, rel=0.05)
    assert np.sqrt(rel.covariance[0, 0]) < 0.1 * sigma_pred


def test_unresolved_bridges_the_epoch_as_before() -> None:
    rel, _ = _last("unresolved")
    assert rel.status is Status.UNRESOLVED and not rel.rotation_partly_observed
    roll = np.degrees(rpy_from_rotation(rel.T_prev_curr[:3, :3]))[0]
    assert roll == pytest.approx(0.0, abs=1e-9)  # the prediction's: the roll is lost
