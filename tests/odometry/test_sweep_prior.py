"""The motion inside an epoch as a MAP estimate (planodom.odometry.sweep_prior) against
constructed ground truths: exact planes, a reference plane off by an error its covariance
allows, and the twist change of a constructed sequence."""

from dataclasses import replace

import numpy as np

from planodom.config.sweep_refine import SweepRefineConfig
from planodom.geometry import se3_exp
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.sweep_motion import epoch_motion
from planodom.odometry.sweep_prior import plane_error_factor, tangent_basis, twist_change
from tests.odometry.test_sweep_motion import TIMES, XI, _scene, epoch_on_curve

TWIST = SweepRefineConfig(prior="twist")


def _rotation_error_rad(out, scan, truth):
    idx = np.searchsorted(out.times, scan.t)
    err = np.linalg.inv(truth) @ out.T_k_t[idx]
    cos = np.clip((np.trace(err[:, :3, :3], axis1=1, axis2=2) - 1) / 2, -1, 1)
    return float(np.max(np.arccos(cos)))


def _with_covariance(plane, sigma_tilt, sigma_d):
    """``plane`` with a fit covariance of ``sigma_tilt`` (rad) about both tangent axes and
    ``sigma_d`` (m) in the offset."""
    B = tangent_basis(plane.normal)
    cov = np.zeros((4, 4))
    cov[:3, :3] = sigma_tilt**2 * B @ B.T
    cov[3, 3] = sigma_d**2
    return replace(plane, covariance=cov)


def test_map_motion_is_exact_on_exact_planes():
    """Exact planes with tiny covariances and a twist change far above the correction's:
    the MAP estimate recovers the constructed motion as the fixed priors do."""
    rng = np.random.default_rng(3)
    planes = [_with_covariance(p, 1e-7, 1e-7) for p in _scene()]
    poses, scan, truth = epoch_on_curve(planes, rng)
    change = np.array([1.0, 1.0])  # rad/s, m/s: the prior holds nothing here
    out = epoch_motion(scan, 1, 0, TIMES, poses, planes, TWIST, 0.0, change)
    assert out is not None
    assert _rotation_error_rad(out, scan, truth) < 1e-6
    idx = np.searchsorted(out.times, scan.t)
    assert np.abs((np.linalg.inv(truth) @ out.T_k_t[idx])[:, :3, 3]).max() < 1e-6


def test_map_motion_does_not_follow_a_reference_plane_error():
    """One wall of the reference is tilted by 0.3 deg, as its covariance (0.3 deg) allows:
    fitted as exact (``prior: fixed``), the motion follows the tilt; with the plane's
    error an unknown (``prior: twist``, the twist change of the constructed motion), the
    motion's error is several times smaller."""
    rng = np.random.default_rng(5)
    true_planes = _scene()
    poses, scan, truth = epoch_on_curve(true_planes, rng)
    tilt = np.deg2rad(0.3)
    planes = [_with_covariance(p, tilt, 0.003) for p in true_planes]
    wall = planes[1]
    n = wall.normal + tilt * tangent_basis(wall.normal)[:, 0]
    planes[1] = replace(wall, normal=n / np.linalg.norm(n))
    fixed = epoch_motion(scan, 1, 0, TIMES, poses, planes, SweepRefineConfig(), 0.001)
    change = np.array([np.deg2rad(1.0), 0.05])  # rad/s, m/s
    ours = epoch_motion(scan, 1, 0, TIMES, poses, planes, TWIST, 0.001, change)
    assert fixed is not None and ours is not None
    e_fixed = _rotation_error_rad(fixed, scan, truth)
    e_ours = _rotation_error_rad(ours, scan, truth)
    assert e_ours < 0.3 * e_fixed


def test_twist_change_is_the_rms_change_of_successive_twists():
    """Steps of twists ``xi_k`` with zero covariance: the change is the rms of the norms
    of ``xi_k - xi_{k-1}`` (rotation and translation parts), over successive OK steps."""
    rng = np.random.default_rng(0)
    dt, n = 0.2, 12
    twists = XI + rng.normal(scale=[0.01, 0.01, 0.05, 0.1, 0.02, 0.01], size=(n, 6))
    poses = [np.eye(4)]
    results: list = [None]
    for k in range(1, n):
        step = se3_exp(twists[k] * dt)
        poses.append(poses[-1] @ step)
        status = Status.UNRESOLVED if k == 6 else Status.OK
        results.append(RelativePose(step, np.zeros((5, 5)), status=status))
    times = dt * np.arange(n)
    pairs = [k for k in range(2, n) if k not in (6, 7)]  # both steps OK
    d = np.array([twists[k] - twists[k - 1] for k in pairs])
    expected = np.sqrt([np.mean(np.sum(d[:, :3] ** 2, 1)), np.mean(np.sum(d[:, 3:] ** 2, 1))])
    got = twist_change(times, np.array(poses), results)
    assert np.allclose(got, expected, rtol=1e-9)


def test_plane_error_factor_reproduces_the_covariance():
    plane = _with_covariance(_scene()[3], 0.01, 0.02)
    F = plane_error_factor(plane, np.zeros(6))
    assert F is not None and np.allclose(F @ F.T, plane.covariance, atol=1e-15)
    assert plane_error_factor(replace(plane, covariance=None), np.zeros(6)) is None
