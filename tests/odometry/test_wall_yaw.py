"""A bridged step whose only planes are a corridor's two walls takes its yaw from them
(``odometry.wall_yaw``, :mod:`planodom.odometry.wall_yaw`), checked against the true
steps the planes were moved by."""

from __future__ import annotations

import numpy as np
import pytest
from planes_factory import observe

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import (
    Plane,
    invert_transform,
    make_transform,
    transform_from_rpy_xyz,
    transform_planes,
)
from planodom.odometry import PlaneOdometry
from planodom.odometry.wall_yaw import walls_yawed, yaw_rotation
from planodom.planes import PlaneSet

ON = PlanodomConfig().updated({"odometry.wall_yaw": True}, source="test")


def _yaw_deg(T: np.ndarray) -> float:
    return float(np.degrees(np.arctan2(T[1, 0], T[0, 0])))


def _step(yaw_deg: float, t: list[float]) -> np.ndarray:
    return make_transform(yaw_rotation(np.radians(yaw_deg)), t)


def _corridor(T_prev_curr: np.ndarray, sigma_deg: float = 0.05) -> tuple[PlaneSet, PlaneSet]:
    """A corridor 3.2 m wide at 10 deg to the x axis and its ground, in the previous
    frame and moved into the current one by the true step (ground tilted 0.3 deg there:
    a level plane must not move the yaw)."""
    a = np.radians(10.0)
    n = np.array([[-np.sin(a), np.cos(a), 0.0], [np.sin(a), -np.cos(a), 0.0], [0, 0, 1.0]])
    d = np.array([1.4, 1.8, 1.0])
    s = np.radians(sigma_deg)
    cov = np.diag([s**2 / 2, s**2 / 2, s**2 / 2, 1e-6])
    n_c, d_c = transform_planes(invert_transform(T_prev_curr), n, d)
    tilt = np.radians(0.3)
    n_c[2] = [np.sin(tilt), 0.0, np.cos(tilt)]
    prev = PlaneSet.from_planes([Plane(n[i], float(d[i]), cov) for i in range(3)])
    curr = PlaneSet.from_planes([Plane(n_c[i], float(d_c[i]), cov) for i in range(3)])
    return prev, curr


def test_the_walls_give_the_true_yaw_where_the_bridge_is_off() -> None:
    truth = _step(1.5, [0.30, 0.02, 0.0])
    prev, curr = _corridor(truth)
    for off_deg in (-6.0, 2.0, 4.0, 7.5):  # within prior_rotation_deg + strict_normal_deg
        bridge = _step(1.5 + off_deg, [0.32, 0.0, 0.0])
        got = walls_yawed(bridge, prev, curr, ON)
        assert _yaw_deg(got) == pytest.approx(1.5, abs=0.01), off_deg  # the ground's 0.3 deg
        np.testing.assert_array_equal(got[:3, 3], bridge[:3, 3])  # translation: the bridge's
    assert walls_yawed(bridge, prev, curr, PlanodomConfig()) is bridge  # off: the same object


def test_walls_beyond_the_gate_leave_the_bridge() -> None:
    prev, curr = _corridor(_step(0.0, [0.30, 0.0, 0.0]))
    bridge = _step(9.0, [0.30, 0.0, 0.0])  # 9 deg off: beyond 5 + 3 deg
    assert walls_yawed(bridge, prev, curr, ON) is bridge


def test_noisy_walls_weigh_by_their_covariances() -> None:
    """Each wall's current normal turned about the vertical (the yaw they give is 0.2 deg
    above and 0.05 below the truth); the previous normals have 1 deg sigmas, the current
    ones 1 and 0.25 deg (a trace of 1.5 sigma^2 each): the yaw is the inverse-variance
    mean of the two, the floor added to each normal."""
    truth = _step(1.0, [0.3, 0.0, 0.0])
    prev, curr = _corridor(truth, sigma_deg=1.0)
    covs = [curr.covariances[0], np.diag([np.radians(0.25) ** 2 / 2] * 3 + [1e-6])]
    turned = [
        Plane(yaw_rotation(np.radians(err)).T @ curr.normals[i], float(curr.offsets[i]), covs[i])
        for i, err in enumerate((0.2, -0.05))
    ]
    walls = PlaneSet.from_planes(turned)
    got = walls_yawed(_step(2.0, [0.3, 0.0, 0.0]), prev.take(np.arange(2)), walls, ON)
    floor = np.radians(PlanodomConfig().odometry.refine_normal_floor_deg) ** 2
    v1 = 1.5 * np.radians(1.0) ** 2 * 2 + 2 * floor
    v2 = 1.5 * np.radians(1.0) ** 2 + 1.5 * np.radians(0.25) ** 2 + 2 * floor
    expected = 1.0 + (0.2 / v1 - 0.05 / v2) / (1 / v1 + 1 / v2)
    assert expected == pytest.approx(1.0368, abs=1e-3)  # by hand: (0.2/3 - 0.05/1.59)/0.96
    assert _yaw_deg(got) == pytest.approx(expected, abs=1e-9)


def _corridor_run(wall_yaw: bool) -> tuple[PlaneOdometry, list[np.ndarray]]:
    """A vehicle ends a turn (0.02 rad an epoch) in a corridor along x: epochs 0-4 see its
    walls, an end wall and the ground (measured), epochs 5-14 the two walls only, while
    the turn's rate falls to 0 and turns back (-0.005 rad an epoch)."""
    walls = [([0.0, -1.0, 0.0], 1.6), ([0.0, 1.0, 0.0], 1.6)]
    others = [([-1.0, 0.0, 0.0], 30.0), ([0.0, 0.0, 1.0], 1.0)]
    cov = np.diag([1e-8] * 3 + [1e-6])
    world = [Plane(np.array(n), d, cov) for n, d in walls + others]
    inc = [0.0] + [0.02] * 4 + [0.015, 0.01, 0.005, 0.0, -0.005] + [-0.005] * 5
    yaw = np.cumsum(inc) - 0.04
    poses = [transform_from_rpy_xyz(0.0, 0.0, yaw[k], 0.3 * k, 0.0, 0.0) for k in range(15)]
    cfg = PlanodomConfig.from_dict({"odometry": {"pipeline": "wocsc", "wall_yaw": wall_yaw}})
    odo = PlaneOdometry(cfg)
    for k, T in enumerate(poses):
        odo.register_planes(observe(world if k < 5 else world[:2], T), time=0.1 * k)
    return odo, poses


def test_a_corridor_after_a_turn_keeps_the_true_heading() -> None:
    for wall_yaw in (False, True):
        odo, poses = _corridor_run(wall_yaw)
        assert all(str(odo.results[k].status) == "unresolved" for k in range(5, 15))
        truth = [invert_transform(poses[0]) @ T for T in poses]  # epoch 0's frame: the world
        err = [_yaw_deg(invert_transform(truth[k]) @ odo.poses[k]) for k in range(5, 15)]
        if wall_yaw:
            assert max(abs(e) for e in err) < 1e-6
        else:  # bridged at the turn's last rate, 0.02 rad an epoch
            lag = np.degrees(np.cumsum([0.005, 0.01, 0.015, 0.02] + [0.025] * 6))
            np.testing.assert_allclose(err, lag, atol=1e-6)


def test_it_is_off_by_default_and_a_bad_value_names_the_field(tmp_path) -> None:
    assert PlanodomConfig().odometry.wall_yaw is False
    (tmp_path / "c.yaml").write_text("odometry: {wall_yaw: true}\n")
    assert PlanodomConfig.from_yaml(tmp_path / "c.yaml").odometry.wall_yaw is True
    (tmp_path / "c.yaml").write_text("odometry: {wall_yaw: sometimes}\n")
    with pytest.raises(ConfigError, match=r"c\.yaml: field 'odometry\.wall_yaw'"):
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")
