"""The oracle: exact at sigma = 0, unbiased with noise, honest about degenerate geometry."""

from __future__ import annotations

import numpy as np
import pytest
from pose_checks import pose_error

from planodom.geometry import invert_transform, se3_exp
from planodom.oracle import deskewed_points, relative_pose, run_oracle, surface_moments
from planodom.scan import Scan
from planodom.simulation import TwistTrajectory
from planodom.simulation.random_world import random_world, simulate_world

#: Patches (centre, normal, in-plane axes half-sizes) of a small world: ground, three walls
#: at 0, 70 and 135 deg, a slanted roof.
PATCHES = [
    ((0.0, 0.0, -1.0), (0.0, 0.0, 1.0), (8.0, 8.0)),
    ((6.0, 0.0, 1.0), (-1.0, 0.0, 0.0), (4.0, 2.0)),
    ((0.0, 7.0, 1.0), (-np.cos(np.radians(70)), -np.sin(np.radians(70)), 0.0), (4.0, 2.0)),
    ((-5.0, -5.0, 1.5), (np.cos(np.radians(45)), np.sin(np.radians(45)), 0.0), (3.0, 2.0)),
    ((-3.0, 4.0, 3.0), (0.3, -0.2, -0.93), (2.0, 2.0)),
]


def _patch_points(rng, centre, normal, half, n=400):
    n_ = np.asarray(normal) / np.linalg.norm(normal)
    a = np.cross(n_, [0.3, 0.5, 0.8])
    a /= np.linalg.norm(a)
    b = np.cross(n_, a)
    uv = rng.uniform(-1, 1, (n, 2)) * half
    return np.asarray(centre) + uv[:, :1] * a + uv[:, 1:] * b, n_


def _epoch(T_world_base, rng, sigma, patches=PATCHES):
    """Points (base frame) and labels of the patches seen from ``T_world_base``, with
    Gaussian noise ``sigma`` along each patch's normal."""
    pts, labels = [], []
    for i, (c, n, half) in enumerate(patches):
        p, nn = _patch_points(rng, c, n, half)
        p = p + sigma * rng.standard_normal((len(p), 1)) * nn
        T = invert_transform(T_world_base)
        pts.append(p @ T[:3, :3].T + T[:3, 3])
        labels.append(np.full(len(p), i))
    return np.concatenate(pts), np.concatenate(labels)


T_PREV = se3_exp(np.array([0.01, -0.02, 0.3, 0.5, -0.2, 0.05]))
T_STEP = se3_exp(np.array([0.004, -0.006, 0.05, 0.4, 0.08, 0.01]))


def test_exact_at_zero_noise_from_a_far_start():
    rng = np.random.default_rng(1)
    prev = surface_moments(*_epoch(T_PREV, rng, 0.0))
    curr = surface_moments(*_epoch(T_PREV @ T_STEP, rng, 0.0))  # other points, same planes
    est = relative_pose(prev, curr)  # from identity, 3 deg and 40 cm away
    rot, trans = pose_error(est.T_prev_curr, T_STEP)
    assert est.status == "ok" and est.n_common == len(PATCHES) and est.measured.all()
    assert rot < 1e-10 and trans < 1e-10


def test_unbiased_with_noise():
    """Mean error over noise draws is zero within 3 standard errors, in all six DoF."""
    sigma, draws, errors = 0.02, 60, []
    for seed in range(draws):
        rng = np.random.default_rng(seed)
        prev = surface_moments(*_epoch(T_PREV, rng, sigma))
        curr = surface_moments(*_epoch(T_PREV @ T_STEP, rng, sigma))
        E = invert_transform(T_STEP) @ relative_pose(prev, curr).T_prev_curr
        errors.append(np.r_[E[2, 1], E[0, 2], E[1, 0], E[:3, 3]])  # small-angle, metres
    e = np.array(errors)
    mean, sem = e.mean(axis=0), e.std(axis=0, ddof=1) / np.sqrt(draws)
    assert np.all(np.abs(mean) < 3.5 * sem)
    assert np.degrees(e[:, :3].std()) < 0.05 and e[:, 3:].std() < 0.01  # and precise


def test_corridor_length_is_not_measured():
    """Floor and two parallel walls: rotation and the across-corridor position measured,
    the length not (degenerate); it keeps the initial guess."""
    corridor = [PATCHES[0], ((0.0, 2.0, 1.0), (0, -1, 0), (6.0, 1.5)),
                ((0.0, -2.0, 1.0), (0, 1, 0), (6.0, 1.5))]  # fmt: skip
    rng = np.random.default_rng(3)
    prev = surface_moments(*_epoch(np.eye(4), rng, 0.0, corridor))
    curr = surface_moments(*_epoch(T_STEP, rng, 0.0, corridor))
    est = relative_pose(prev, curr, np.eye(4))
    assert est.status == "degenerate"
    assert est.measured.tolist() == [True, True, True, False, True, True]
    assert abs(est.T_prev_curr[0, 3]) < 0.05  # x stays near the guess (0), not 0.4
    rot, _ = pose_error(est.T_prev_curr, T_STEP)
    assert rot < 1e-9  # the rotation is exact all the same


def test_deskewed_points_undo_a_constant_twist():
    xi = np.array([0.1, -0.05, 0.6, 2.0, 0.3, 0.0])
    traj = TwistTrajectory(se3_exp(np.array([0, 0, 0.4, 5.0, 1.0, 0.0])), xi)
    rng = np.random.default_rng(0)
    world = rng.uniform(-10, 10, (200, 3))
    t = np.sort(rng.uniform(0, 0.1, 200))
    t_k = 1.3
    T = traj.poses(t_k + t)
    base_at_t = np.einsum("nji,nj->ni", T[:, :3, :3], world - T[:, :3, 3])
    got = deskewed_points(Scan(base_at_t, t=t), traj, t_k)
    Tk = invert_transform(traj.pose(t_k))
    assert np.allclose(got, world @ Tk[:3, :3].T + Tk[:3, 3], atol=1e-9)


@pytest.mark.parametrize("family", ["rig2d", "lidar32"])
def test_exact_on_a_simulated_world_at_zero_noise(family):
    world = random_world(0, kind="outdoor", rig=family)
    run = simulate_world(world, 0.0, n_epochs=8, all_fields=True)
    orc = run_oracle(run.scans, run.times, world.trajectory, world.scene)
    gt = invert_transform(run.poses[0])[None] @ run.poses
    assert orc.n_unresolved == 0 and np.all(orc.n_planes >= 3)
    for k in range(1, len(run)):
        if orc.statuses[k] == "ok":
            step = invert_transform(gt[k - 1]) @ gt[k]
            rot, trans = pose_error(invert_transform(orc.poses[k - 1]) @ orc.poses[k], step)
            assert rot < 1e-9 and trans < 1e-9


def test_jacobian_is_the_forward_difference_of_the_residuals():
    """The Jacobian's stored perturbations give each column bit for bit as the forward
    difference computed here, through ``se3_exp`` of the step (its definition)."""
    from planodom.oracle import _jacobian, _residuals, _roots

    rng = np.random.default_rng(3)
    prev = surface_moments(*_epoch(T_PREV, rng, 0.01))
    curr = surface_moments(*_epoch(T_PREV @ T_STEP, rng, 0.01))
    roots = (_roots(prev.scatter), _roots(curr.scatter))
    r0 = _residuals(T_STEP, prev, curr, roots)
    for h in (1e-7, 1e-6):
        J = _jacobian(T_STEP, prev, curr, roots, r0, h)
        for i, e in enumerate(np.eye(6)):
            col = (_residuals(T_STEP @ se3_exp(h * e), prev, curr, roots) - r0) / h
            assert np.array_equal(J[:, i], col)
