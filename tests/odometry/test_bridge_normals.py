"""A bridged step whose only planes are a corridor's two walls takes its yaw from them
(``odometry.bridge_normals``, :mod:`planodom.odometry.bridge_normals`), checked against the true
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
from planodom.odometry.bridge_normals import normals_bridged
from planodom.planes import PlaneSet
from planodom.rotvec import rotation_matrices

ON = PlanodomConfig().updated({"odometry.bridge_normals": True}, source="test")
A = np.radians(10.0)
ALONG = np.array([np.cos(A), np.sin(A), 0.0])  # the corridor's axis
ACROSS = np.array([-np.sin(A), np.cos(A), 0.0])  # its walls' normal


def _rz(deg: float) -> np.ndarray:
    return rotation_matrices(np.array([[0.0, 0.0, np.radians(deg)]]))[0]


def _yaw_deg(T: np.ndarray) -> float:
    return float(np.degrees(np.arctan2(T[1, 0], T[0, 0])))


def _turned(T: np.ndarray, axis, deg: float) -> np.ndarray:
    """``T`` with its rotation turned by ``deg`` about ``axis`` (reference frame)."""
    R = rotation_matrices((np.radians(deg) * np.asarray(axis, dtype=float))[None])[0]
    return make_transform(R @ T[:3, :3], T[:3, 3])


def _angle_deg(Ra: np.ndarray, Rb: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(Ra.T @ Rb) - 1) / 2, -1, 1))))


def _corridor(T_prev_curr: np.ndarray, sigma_deg: float = 0.05) -> tuple[PlaneSet, PlaneSet]:
    """A corridor 3.2 m wide at 10 deg to the x axis (its two walls, normals towards the
    sensor) and its ground, in the previous frame and moved into the current one by the
    true step."""
    n = np.array([ACROSS, -ACROSS, [0, 0, 1.0]])
    d = np.array([1.4, 1.8, 1.0])
    s = np.radians(sigma_deg)
    cov = np.diag([s**2 / 2, s**2 / 2, s**2 / 2, 1e-6])
    n_c, d_c = transform_planes(invert_transform(T_prev_curr), n, d)
    prev = PlaneSet.from_planes([Plane(n[i], float(d[i]), cov) for i in range(3)])
    curr = PlaneSet.from_planes([Plane(n_c[i], float(d_c[i]), cov) for i in range(3)])
    return prev, curr


def test_the_walls_give_the_true_heading_and_roll_where_the_bridge_is_off() -> None:
    truth = transform_from_rpy_xyz(0.0, 0.0, np.radians(1.5), 0.30, 0.02, 0.0)
    prev, curr = (p.take(np.arange(2)) for p in _corridor(truth))  # the walls only
    for yaw_off in (-6.0, 2.0, 4.0, 6.5):  # within prior_rotation_deg + strict_normal_deg
        bridge = _turned(_turned(truth, [0, 0, 1.0], yaw_off), ALONG, 1.0)
        bridge[:3, 3] = [0.32, 0.0, 0.0]
        got = normals_bridged(bridge, prev, curr, ON)
        # each wall's normal turned onto the reference's; the rotation about it (second
        # order in the two turns, 0.05 deg at 6 deg) stays the bridge's
        np.testing.assert_allclose(curr.normals @ got[:3, :3].T, prev.normals, atol=1e-9)
        assert _yaw_deg(got) == pytest.approx(1.5, abs=0.06), yaw_off
        np.testing.assert_array_equal(got[:3, 3], bridge[:3, 3])  # translation: the bridge's
    assert normals_bridged(bridge, prev, curr, PlanodomConfig()) is bridge  # off: the same


def test_the_rotation_about_the_walls_normal_stays_the_bridges_unless_the_ground_sees_it() -> None:
    truth = transform_from_rpy_xyz(0.0, 0.0, np.radians(1.5), 0.30, 0.02, 0.0)
    prev, curr = _corridor(truth)
    bridge = _turned(truth, ACROSS, 2.0)  # about the walls' normal: only the ground sees it
    walls = (p.take(np.arange(2)) for p in (prev, curr))
    kept = normals_bridged(bridge, *walls, ON)
    assert _angle_deg(kept[:3, :3], bridge[:3, :3]) < 1e-9
    with_ground = normals_bridged(bridge, prev, curr, ON)
    assert _angle_deg(with_ground[:3, :3], truth[:3, :3]) < 1e-5


def test_walls_beyond_the_gate_leave_the_bridge() -> None:
    truth = transform_from_rpy_xyz(0.0, 0.0, 0.0, 0.30, 0.0, 0.0)
    prev, curr = _corridor(truth)
    bridge = _turned(truth, [0, 0, 1.0], 9.0)  # 9 deg off: beyond 5 + 3 deg
    walls = (p.take(np.arange(2)) for p in (prev, curr))
    assert normals_bridged(bridge, *walls, ON) is bridge
    got = normals_bridged(bridge, prev, curr, ON)  # the ground alone: it sees no yaw
    assert _angle_deg(got[:3, :3], bridge[:3, :3]) < 1e-9


def test_noisy_walls_weigh_by_their_covariances() -> None:
    """Each wall's current normal turned about the vertical (the yaw they give is 0.2 deg
    above and 0.05 below the truth); the previous normals have 1 deg sigmas, the current
    ones 1 and 0.25 deg (a trace of 1.5 sigma^2 each): the yaw is the inverse-variance
    mean of the two (of their sines, equal here to 1e-7 deg), the floor added to each."""
    truth = transform_from_rpy_xyz(0.0, 0.0, np.radians(1.0), 0.3, 0.0, 0.0)
    prev, curr = _corridor(truth, sigma_deg=1.0)
    covs = [curr.covariances[0], np.diag([np.radians(0.25) ** 2 / 2] * 3 + [1e-6])]
    turned = [
        Plane(_rz(e).T @ curr.normals[i], float(curr.offsets[i]), covs[i])
        for i, e in enumerate((0.2, -0.05))
    ]
    bridge = transform_from_rpy_xyz(0.0, 0.0, np.radians(2.0), 0.3, 0.0, 0.0)
    walls = PlaneSet.from_planes(turned)
    got = normals_bridged(bridge, prev.take(np.arange(2)), walls, ON)
    floor = np.radians(PlanodomConfig().odometry.refine_normal_floor_deg) ** 2
    v1 = 1.5 * np.radians(1.0) ** 2 * 2 + 2 * floor
    v2 = 1.5 * np.radians(1.0) ** 2 + 1.5 * np.radians(0.25) ** 2 + 2 * floor
    expected = 1.0 + (0.2 / v1 - 0.05 / v2) / (1 / v1 + 1 / v2)
    assert expected == pytest.approx(1.0368, abs=1e-3)  # by hand: (0.2/3 - 0.05/1.59)/0.96
    assert _yaw_deg(got) == pytest.approx(expected, abs=1e-6)


def _corridor_run(on: bool) -> tuple[PlaneOdometry, list[np.ndarray]]:
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
    cfg = PlanodomConfig.from_dict({"odometry": {"pipeline": "wocsc", "bridge_normals": on}})
    odo = PlaneOdometry(cfg)
    for k, T in enumerate(poses):
        odo.register_planes(observe(world if k < 5 else world[:2], T), time=0.1 * k)
    return odo, poses


def test_a_corridor_after_a_turn_keeps_the_true_heading() -> None:
    for on in (False, True):
        odo, poses = _corridor_run(on)
        assert all(str(odo.results[k].status) == "unresolved" for k in range(5, 15))
        truth = [invert_transform(poses[0]) @ T for T in poses]  # epoch 0's frame: the world
        err = [_yaw_deg(invert_transform(truth[k]) @ odo.poses[k]) for k in range(5, 15)]
        if on:  # the whole rotation: the walls' normal's part is the bridge's, right here
            assert max(abs(e) for e in err) < 1e-6
            assert (
                max(_angle_deg(truth[k][:3, :3], odo.poses[k][:3, :3]) for k in range(5, 15)) < 1e-6
            )
        else:  # bridged at the turn's last rate, 0.02 rad an epoch
            lag = np.degrees(np.cumsum([0.005, 0.01, 0.015, 0.02] + [0.025] * 6))
            np.testing.assert_allclose(err, lag, atol=1e-6)


def test_it_is_off_by_default_and_a_bad_value_names_the_field(tmp_path) -> None:
    assert PlanodomConfig().odometry.bridge_normals is False
    (tmp_path / "c.yaml").write_text("odometry: {bridge_normals: weighed}\n")
    assert PlanodomConfig.from_yaml(tmp_path / "c.yaml").odometry.bridge_normals == "weighed"
    (tmp_path / "c.yaml").write_text("odometry: {bridge_normals: true}\n")
    assert PlanodomConfig.from_yaml(tmp_path / "c.yaml").odometry.bridge_normals is True
    (tmp_path / "c.yaml").write_text("odometry: {bridge_normals: sometimes}\n")
    with pytest.raises(ConfigError, match=r"c\.yaml: field 'odometry\.bridge_normals'"):
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")


WEIGHED = PlanodomConfig().updated({"odometry.bridge_normals": "weighed"}, source="test")


def test_weighed_with_an_exact_bridge_keeps_it_and_with_no_weight_takes_the_normals() -> None:
    truth = transform_from_rpy_xyz(0.0, 0.0, np.radians(1.5), 0.30, 0.02, 0.0)
    prev, curr = (p.take(np.arange(2)) for p in _corridor(truth))
    bridge = _turned(_turned(truth, [0, 0, 1.0], 3.0), ALONG, 1.0)
    np.testing.assert_allclose(
        normals_bridged(bridge, prev, curr, WEIGHED, 0.0), bridge, atol=1e-12
    )
    free = normals_bridged(bridge, prev, curr, WEIGHED, 1e12)
    np.testing.assert_allclose(free, normals_bridged(bridge, prev, curr, ON), atol=1e-9)
    # without a variance (none known) it is ``true``'s correction; off: the bridge
    np.testing.assert_allclose(normals_bridged(bridge, prev, curr, WEIGHED), free, atol=1e-12)
    assert normals_bridged(bridge, prev, curr, PlanodomConfig(), 0.0) is bridge


def test_weighed_is_the_minimum_of_the_normals_and_the_bridges_errors() -> None:
    """Two horizontal walls and a bridge off in yaw only: the yaw ``y`` minimises ``W (2 -
    2 cos(y - y_w)) + (y - y_b)^2 / v`` (``W`` the walls' summed weights, ``y_w`` the
    truth, ``y_b`` the bridge's), so ``W sin(y - y_w) + (y - y_b) / v = 0``: solved here
    by bisection, for a bridge sigma under, equal to and over the walls'."""
    truth = transform_from_rpy_xyz(0.0, 0.0, np.radians(1.5), 0.30, 0.02, 0.0)
    prev, curr = (p.take(np.arange(2)) for p in _corridor(truth, sigma_deg=0.2))
    floor = np.radians(PlanodomConfig().odometry.refine_normal_floor_deg) ** 2
    W = 2.0 / (2 * 1.5 * np.radians(0.2) ** 2 + 2 * floor)
    y_w, y_b = np.radians(1.5), np.radians(1.5 + 2.0)
    bridge = _turned(truth, [0, 0, 1.0], 2.0)
    for v in (0.25 / W, 1.0 / W, 4.0 / W):
        lo, hi = y_w, y_b  # the root lies between the two
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if W * np.sin(mid - y_w) + (mid - y_b) / v < 0 else (lo, mid)
        got = normals_bridged(bridge, prev, curr, WEIGHED, v)
        assert _yaw_deg(got) == pytest.approx(np.degrees(lo), abs=1e-7), v
        # near the linear blend: the weight of the walls W / (W + 1/v)
        linear = 1.5 + 2.0 / (1.0 + W * v)
        assert _yaw_deg(got) == pytest.approx(linear, abs=1e-3)


def test_weighed_takes_the_walls_in_a_long_bridge_through_a_turns_end() -> None:
    """The corridor run of :func:`_corridor_run` with ``weighed``: ten bridged epochs whose
    held rate is 0.005-0.025 rad an epoch off; the walls (exact, stated at the floor) are
    weighed against a bridge sigma that grows with every epoch, so the yaw error stays
    below the bridge's lag (closed form in the default's test) and shrinks to the walls'
    over the stretch. (The rate was constant before: the model holds the bridge precise
    at first, and the first bridged step keeps nearly all of its lag.)"""
    walls = [([0.0, -1.0, 0.0], 1.6), ([0.0, 1.0, 0.0], 1.6)]
    others = [([-1.0, 0.0, 0.0], 30.0), ([0.0, 0.0, 1.0], 1.0)]
    cov = np.diag([1e-8] * 3 + [1e-6])
    world = [Plane(np.array(n), d, cov) for n, d in walls + others]
    inc = [0.0] + [0.02] * 4 + [0.015, 0.01, 0.005, 0.0, -0.005] + [-0.005] * 5
    yaw = np.cumsum(inc) - 0.04
    poses = [transform_from_rpy_xyz(0.0, 0.0, yaw[k], 0.3 * k, 0.0, 0.0) for k in range(15)]
    cfg = PlanodomConfig.from_dict({"odometry": {"pipeline": "wocsc", "bridge_normals": "weighed"}})
    odo = PlaneOdometry(cfg)
    for k, T in enumerate(poses):
        odo.register_planes(observe(world if k < 5 else world[:2], T), time=0.1 * k)
    truth = [invert_transform(poses[0]) @ T for T in poses]
    err = np.abs([_yaw_deg(invert_transform(truth[k]) @ odo.poses[k]) for k in range(5, 15)])
    lag = np.degrees(np.cumsum([0.005, 0.01, 0.015, 0.02] + [0.025] * 6))
    assert np.all(err < lag) and np.all(err[5:] < 0.1 * lag[5:]) and err[-1] < 0.001 * lag[-1]
