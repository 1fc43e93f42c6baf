"""The motion inside an epoch measured against reference planes
(planodom.odometry.sweep_motion) against a constructed ground truth."""

import numpy as np

from planodom.config.sweep_refine import SweepRefineConfig
from planodom.geometry import Plane, PlaneSupport, invert_transform, se3_exp
from planodom.odometry.interpolate import interpolated_motion
from planodom.odometry.sweep_motion import assign, epoch_motion
from planodom.rotvec import rotation_matrices
from planodom.scan import Scan

XI = np.array([0.02, -0.01, 0.3, 2.0, 0.1, 0.0])  # rad/s, m/s
TIMES = np.array([0.0, 0.2, 0.4, 0.6])


def _square(normal, offset, half=30.0):
    """A plane with a square support of side 2 ``half`` (m) about its foot point."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    a = np.cross(n, [1.0, 0, 0] if abs(n[0]) < 0.9 else [0, 1.0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    c = -offset * n
    corners = ((1, 1), (-1, 1), (-1, -1), (1, -1))
    poly = np.array([c + half * (sa * a + sb * b) for sa, sb in corners])
    return Plane(n, offset, support=PlaneSupport(centroid=c, polygon=poly, n_points=100))


def test_assign_takes_the_nearest_plane_within_gate_and_support():
    ground = _square([0, 0, 1.0], 1.5, half=2.0)  # z = -1.5, |x|, |y| <= 2
    wall = _square([1.0, 0, 0], -5.0)  # x = 5
    pts = np.array([[0.0, 0, -1.48], [4.97, 0, -1.0], [0.0, 0, -1.0], [3.5, 0, -1.5]])
    # the last one lies on the ground's plane but 1.5 m beyond its support (margin 1 m)
    assert assign(pts, [ground, wall], 0.1, 1.0).tolist() == [0, 1, -1, -1]
    assert assign(pts, [ground, wall], 0.1, 2.0).tolist() == [0, 1, -1, 0]


def _scene():
    """Reference planes (frame of epoch 0): ground and three walls."""
    return [_square([0, 0, 1.0], 1.5), _square([1.0, 0, 0], -12.0),
            _square([0, 1.0, 0], -8.0), _square([-0.6, -0.8, 0], -9.0)]  # fmt: skip


def epoch_on_curve(planes, rng):
    """Epoch 1's points on ``planes`` (frame of epoch 0), seen along the curve through
    constant-twist poses times a correction of the model's form (rotation quadratic,
    translation linear in time): the poses at TIMES, the scan, and the truth T_1_t."""
    poses = se3_exp(TIMES[:, None] * XI)
    t = np.sort(np.r_[0.0, rng.uniform(0.0, 0.15, 1999)])  # point times after t_1
    T_curve = interpolated_motion(TIMES, poses, TIMES[0], TIMES[1] + t, 3)
    s = (t - 0.075) / 0.075
    w = np.deg2rad(0.05) * np.c_[s, -(s**2), 0.5 * s - s**2]
    v = 0.004 * np.c_[1 + s, -s, 0.5 * s]
    C = np.tile(np.eye(4), (len(t), 1, 1))
    C[:, :3, :3], C[:, :3, 3] = rotation_matrices(w), v
    T_true = T_curve @ C  # T_0_t
    which = rng.integers(0, len(planes), len(t))
    p0 = np.empty((len(t), 3))
    for i, j in enumerate(which):
        n, d = planes[j].normal, planes[j].offset
        q = rng.uniform(-6, 6, 3) + T_true[i, :3, 3]
        q[2] = rng.uniform(-1.0, 4.0)  # walls seen above the ground, not at their foot
        p0[i] = q - (n @ q + d) * n
    T_t_0 = np.array([invert_transform(T) for T in T_true])
    pts = np.einsum("nij,nj->ni", T_t_0[:, :3, :3], p0) + T_t_0[:, :3, 3]
    return poses, Scan(pts, t=t), invert_transform(T_true[0]) @ T_true


def test_epoch_motion_recovers_a_motion_off_the_curve():
    """The true motion of epoch 1 in the frame of epoch 0 is the curve through constant-
    twist poses times a correction of the model's form (rotation quadratic, translation
    linear in time): measured at sigma = 0, the motion inside the epoch is exact (to
    the prior's pull)."""
    planes = _scene()
    poses, scan, truth = epoch_on_curve(planes, np.random.default_rng(3))
    t, pts = scan.t, scan.points
    out = epoch_motion(scan, 1, 0, TIMES, poses, planes, SweepRefineConfig(), 0.0)
    assert out is not None and out.n_planes == 4
    idx = np.searchsorted(out.times, t)
    err = np.linalg.inv(truth) @ out.T_k_t[idx]
    # what is left is the zero-mean prior's pull (5e-8 rad here), far below 1e-4 deg
    assert np.abs(err[:, :3, :3] - np.eye(3)).max() < 1e-6
    assert np.abs(err[:, :3, 3]).max() < 1e-6
    assert out.rms_m[1] < 1e-6 < 1e-3 < out.rms_m[0]
    flat = out.deskewed(scan)
    expected = np.einsum("nij,nj->ni", truth[:, :3, :3], pts) + truth[:, :3, 3]
    assert np.abs(flat.points - expected).max() < 1e-4 and not flat.t.any()


def test_epoch_motion_needs_three_plane_directions():
    poses = se3_exp(TIMES[:, None] * XI)
    planes = _scene()[:2]  # ground and one wall: a translation left open
    t = np.linspace(0.0, 0.15, 400)
    pts = np.c_[np.full_like(t, 11.0), np.linspace(-3, 3, len(t)), np.full_like(t, -1.5)]
    out = epoch_motion(Scan(pts, t=t), 1, 0, TIMES, poses, planes, SweepRefineConfig(), 0.0)
    assert out is None
