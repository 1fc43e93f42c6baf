"""The plane-map odometry's degenerate translation (from the prediction) and its motion
bound gate, on synthetic scenes with a known motion (issue 11)."""

from __future__ import annotations

import numpy as np
import pytest
from planemap_factory import plane_points, planes_of, pose, scene_points

from planodom.config import PlanodomConfig
from planodom.odometry import Status, run_odometry
from planodom.odometry.planemap import PlaneMapOdometry

#: True motion per epoch: 0.5 m along the corridor (x).
STEP = 0.5
#: Yaw of one corridor wall, deg: it observes the motion along the corridor, weakly.
SKEW_DEG = 0.3


def _corridor(T_world_base: np.ndarray, k: int, end_wall: bool, bias_m: float) -> list:
    """Planes of a corridor along x seen from ``T_world_base`` (scan frame): the ground, a
    wall at y = -3 and, across, a wall yawed by ``SKEW_DEG`` whose fitted offset is off by
    ``bias_m`` (a plane fitted across a bend: a model error, not noise); with
    ``end_wall`` also a wall across the corridor at x = 20 (the motion is observed)."""
    rng = np.random.default_rng(30 + k)
    yaw = np.radians(SKEW_DEG)
    skew = np.array([-np.sin(yaw), -np.cos(yaw), 0.0])  # facing the corridor (-y)
    x0 = T_world_base[0, 3]  # the walls seen are those around the sensor
    sets = [plane_points(rng, [0, 0, 1.0], 1.8, [x0 + dx, 0, -1.8], 6, 500) for dx in (-6, 0, 6)]
    sets += [plane_points(rng, [0, 1.0, 0], 3.0, [x0 + dx, -3, 0], 6, 300) for dx in (-6, 0, 6)]
    sets += [plane_points(rng, skew, 3.0 + bias_m, [x0 + dx, 3, 0], 6, 300) for dx in (-6, 6)]
    if end_wall:
        sets.append(plane_points(rng, [-1.0, 0, 0], 20.0, [20, 0, 0], 5, 400))
    inv = np.linalg.inv(T_world_base)
    return planes_of([S @ inv[:3, :3].T + inv[:3, 3] for S in sets])


def _walk(mode: str, gate: bool = True) -> tuple[PlaneMapOdometry, list]:
    """Two epochs see the end wall (the velocity is measured), then it is out of view and
    the skewed wall's offset drifts by 2 cm an epoch."""
    changes = {"planemap.degenerate_translation": mode, "planemap.motion_bound_gate": gate}
    cfg = PlanodomConfig().updated(changes)
    odo = PlaneMapOdometry(cfg)
    results = []
    for k in range(6):
        truth = pose([0, 0, 0], [STEP * k, 0, 0])
        est = odo.estimate(_corridor(truth, k, end_wall=k < 2, bias_m=0.02 * max(k - 1, 0)))
        odo.commit(est)
        results.append(est.relative)
    return odo, results


def test_a_degenerate_epoch_moves_along_the_corridor_as_predicted() -> None:
    odo, results = _walk("prediction")
    assert [r.status for r in results[1:]] == [Status.OK] + [Status.DEGENERATE] * 4
    # the velocity measured at epoch 1 is the truth; the degenerate epochs keep it along x
    # (across it the biased wall moves the epochs by a centimetre each: not this test's)
    assert odo.pose[0, 3] == pytest.approx(5 * STEP, abs=0.02)
    for r in results[2:]:
        assert r.T_prev_curr[0, 3] == pytest.approx(STEP, abs=0.01)
        # its uncertainty along x is the prediction's, not the registration's weak one
        assert r.sigmas5[3] >= 0.1 > r.sigmas5[4]


def test_the_registration_alone_follows_the_biased_wall_along_the_corridor() -> None:
    """Without the prediction the weak information moves the epoch metres along x: the
    case above would fail without the fix (and the motion bound gate, off here, bridges
    such epochs once they exceed the bounds)."""
    odo, results = _walk("registration", gate=False)
    assert all(r.status is Status.DEGENERATE for r in results[2:])
    assert abs(odo.pose[0, 3] - 5 * STEP) > 1.0


def _scans(poses: list[np.ndarray]) -> list:
    out = []
    for k, T in enumerate(poses):
        inv = np.linalg.inv(T)
        sets = scene_points(np.random.default_rng(10 + k))
        out.append(planes_of([S @ inv[:3, :3].T + inv[:3, 3] for S in sets]))
    return out


def _bounded(gate: bool) -> PlanodomConfig:
    """Motion bounds of 0.5 m / 5 deg an epoch, and the gate on or off."""
    return PlanodomConfig().updated(
        {
            "association.max_translation_m": 0.5,
            "association.max_rotation_deg": 5.0,
            "planemap.laser_bias_m": 0.0,
            "planemap.motion_bound_gate": gate,
            "odometry.pipeline": "map",
        }
    )


@pytest.mark.parametrize(
    "jump",
    [pose([0, 0, 2], [0.8, 0.1, 0]), pose([0, 0, 8], [0.2, 0, 0])],
    ids=["translation", "rotation"],
)
def test_a_step_beyond_the_motion_bounds_is_inconsistent_and_bridged(jump: np.ndarray) -> None:
    step = pose([0, 0, 2], [0.3, 0.05, 0])  # within the bounds
    poses = [np.eye(4), step, step @ step]
    poses.append(poses[-1] @ jump)
    scans = _scans(poses)
    # the registration itself finds the jump (gate off: the truth, OK)
    free = run_odometry(scans, _bounded(gate=False))
    assert free.statuses == ["first", "ok", "ok", "ok"]
    np.testing.assert_allclose(free.poses[-1], poses[-1], atol=1e-6)
    run = run_odometry(scans, _bounded(gate=True))
    last = run.results[-1]
    assert run.statuses[:3] == ["first", "ok", "ok"]
    assert last.status is Status.UNRESOLVED and last.inconsistent
    assert len(last.associations) == 0
    # bridged by constant velocity: the previous step repeated
    np.testing.assert_allclose(run.poses[-1], poses[2] @ step, atol=1e-6)


def test_the_gate_judges_only_the_estimate_kept() -> None:
    """An estimate (one extraction tried) beyond the bounds keeps its status, so that the
    streaming odometry can still refine or replace it; the one kept is judged."""
    step = pose([0, 0, 2], [0.3, 0.05, 0])
    poses = [np.eye(4), step, step @ step]
    poses.append(poses[-1] @ pose([0, 0, 2], [0.8, 0.1, 0]))  # beyond 0.5 m
    scans = _scans(poses)
    odo = PlaneMapOdometry(_bounded(gate=True))
    for scan in scans[:3]:
        est = odo.estimate(scan)
        assert not est.beyond_bounds and odo.judged(est) is est
        odo.commit(est)
    attempt = odo.estimate(scans[3])
    assert attempt.relative.status is Status.OK and attempt.beyond_bounds
    np.testing.assert_allclose(attempt.T, poses[3], atol=1e-6)  # the registration's truth
    kept = odo.judged(attempt)
    assert kept.relative.status is Status.UNRESOLVED and kept.relative.inconsistent
    np.testing.assert_allclose(kept.T, poses[2] @ step, atol=1e-6)  # constant velocity
    off = PlaneMapOdometry(_bounded(gate=False))
    for scan in scans[:3]:
        off.commit(off.estimate(scan))
    attempt = off.estimate(scans[3])
    assert attempt.beyond_bounds and off.judged(attempt) is attempt  # off: reported only
