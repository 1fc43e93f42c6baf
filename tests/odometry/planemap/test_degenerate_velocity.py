"""The plane-map odometry's constant velocity after a degenerate epoch
(``planemap.degenerate_velocity``), on a synthetic corridor with a known motion."""

from __future__ import annotations

import numpy as np
import pytest
from planemap_factory import plane_points, planes_of, pose
from scipy.spatial.transform import Rotation

from planodom.config import PlanodomConfig
from planodom.odometry import Status
from planodom.odometry.planemap import PlaneMapOdometry

#: True motion of the fully observed epochs: 0.5 m along the corridor (x).
STEP = pose([0, 0, 0], [0.5, 0, 0])
#: True motion of the first epoch and of the degenerate one: the same, turned by 0.5 deg of
#: yaw (the first gives the prediction's deviations, hence the gates, their size).
TURN = pose([0, 0, 0.5], [0.5, 0, 0])


def _corridor(T_world_base: np.ndarray, k: int, view: str) -> list:
    """Planes of a corridor along x seen from ``T_world_base`` (scan frame): ``full``, the
    ground, two walls and a wall across at x = 20 (everything observed); ``corridor``,
    without the end wall (the motion along x unobserved: degenerate); ``ground``, three
    ground patches only (too few planes: unresolved)."""
    rng = np.random.default_rng(50 + k)
    x0 = T_world_base[0, 3]
    sets = [plane_points(rng, [0, 0, 1.0], 1.8, [x0 + dx, 0, -1.8], 6, 500) for dx in (-6, 0, 6)]
    if view != "ground":
        sets += [plane_points(rng, [0, 1.0, 0], 3.0, [x0 + dx, -3, 0], 6, 300) for dx in (-6, 6)]
        sets += [plane_points(rng, [0, -1.0, 0], 3.0, [x0 + dx, 3, 0], 6, 300) for dx in (-6, 6)]
    if view == "full":
        sets.append(plane_points(rng, [-1.0, 0, 0], 20.0, [20, 0, 0], 5, 400))
    inv = np.linalg.inv(T_world_base)
    return planes_of([S @ inv[:3, :3].T + inv[:3, 3] for S in sets])


def _yaw_deg(T: np.ndarray) -> float:
    return float(Rotation.from_matrix(T[:3, :3]).as_euler("xyz", degrees=True)[2])


@pytest.mark.parametrize("mode", ["kept", "step"])
def test_an_unresolved_epoch_after_a_degenerate_one_is_bridged_by_the_last_full_step(
    mode: str,
) -> None:
    """Three fully observed epochs (the last step STEP), one degenerate epoch that turns
    (TURN, its rotation measured), then one with the ground alone (unresolved, bridged):
    ``kept`` bridges with STEP, ``step`` repeats the degenerate epoch's turn."""
    odo = PlaneMapOdometry(PlanodomConfig().updated({"planemap.degenerate_velocity": mode}))
    truth = [np.eye(4)]
    for T_rel in (TURN, STEP, TURN, STEP):
        truth.append(truth[-1] @ T_rel)
    views = ["full", "full", "full", "corridor", "ground"]
    results = []
    for k, (T, view) in enumerate(zip(truth, views, strict=True)):
        est = odo.estimate(_corridor(T, k, view))
        odo.commit(est)
        results.append(est.relative)
    statuses = [r.status for r in results[1:]]
    assert statuses == [Status.OK, Status.OK, Status.DEGENERATE, Status.UNRESOLVED]
    # the degenerate epoch measured its turn
    assert _yaw_deg(results[3].T_prev_curr) == pytest.approx(0.5, abs=0.02)
    bridge = results[4].T_prev_curr
    expected = STEP if mode == "kept" else results[3].T_prev_curr
    assert _yaw_deg(bridge) == pytest.approx(_yaw_deg(expected), abs=1e-6)
    atol = 0.01 if mode == "kept" else 1e-9  # kept: the last step measured, not the truth
    np.testing.assert_allclose(bridge[:3, 3], expected[:3, 3], atol=atol)
