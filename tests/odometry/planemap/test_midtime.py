"""Registering lidar sweeps at their middles (``planemap.reference_time: middle``)."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import Plane, invert_transform, se3_exp
from planodom.metrics import per_epoch_errors, relative_motions
from planodom.odometry import run_odometry
from planodom.odometry.planemap.midtime import MiddleTimed, at_epoch_times, first_pose
from planodom.odometry.relative import RelativePose
from planodom.odometry.run import OdometryRun
from planodom.scan import Scan
from planodom.simulation import simulate_named

XI0 = np.array([0.02, -0.01, 0.35, 8.0, 0.3, 0.05])  # rad/s, m/s
ACC = np.array([0.01, 0.02, -0.4, 1.5, -0.2, 0.0])  # their change per second


def _truth(t: float) -> np.ndarray:
    """A smooth motion in closed form: ``T_world_base`` at ``t`` s."""
    return se3_exp(t * XI0 + 0.5 * t**2 * ACC)


def test_at_epoch_times_moves_poses_steps_and_planes_to_the_epoch_times():
    times = np.arange(12) * 0.1
    offsets = 0.05 + 0.002 * np.sin(np.arange(12))  # sweeps' middles, a little uneven
    M = np.array([_truth(t + m) for t, m in zip(times, offsets, strict=True)])
    M = invert_transform(M[0])[None] @ M
    world_plane = Plane(np.array([0.6, 0.8, 0.0]), -5.0)
    results: list[RelativePose | None] = [None] + [
        RelativePose(invert_transform(M[k - 1]) @ M[k], None, prev=k - 1, curr=k)
        for k in range(1, 12)
    ]
    planes = [[world_plane.transformed(invert_transform(P))] for P in M]
    run = OdometryRun(M, times + offsets, results, np.ones(12, int), planes)

    out = at_epoch_times(run, times, order=3)

    T = np.array([_truth(t) for t in times])
    T = invert_transform(T[0])[None] @ T
    assert np.allclose(out.times, times)
    assert np.allclose(out.poses[0], np.eye(4), atol=1e-12)
    # the first pose from the least-squares quadratic over the first five middles (0.4 s):
    # the motion's third-order terms, ~1e-4 over the run; the steps from the cubic through
    # poses 0.1 s apart: ~1e-6
    assert np.abs(out.poses - T).max() < 1e-4
    for k in range(1, 12):
        r = out.results[k]
        assert r is not None
        tol = 1e-4 if k == 1 else 2e-5  # the first step starts at the extrapolated pose
        assert np.abs(r.T_prev_curr - invert_transform(T[k - 1]) @ T[k]).max() < tol
    # the planes: the world plane (in the frame of the first mid pose) in each epoch's
    # base frame at its epoch time
    to_world = invert_transform(_truth(times[0] + offsets[0]))
    for k in range(12):
        expected = world_plane.transformed(invert_transform(to_world @ _truth(times[k])))
        got = out.planes[k][0]
        assert np.allclose(got.normal, expected.normal, atol=2e-5)
        assert abs(got.offset - expected.offset) < 2e-4


def test_at_epoch_times_does_not_amplify_an_early_step_error_into_the_whole_run():
    # constant twist, the second middle pose off by 1 mrad of yaw: the first epoch time,
    # half a spacing before the first middle, is extrapolated; the run's first pose is the
    # identity, so its error turns every later pose. The cubic through the first four
    # would weight that step error by 2.19 (a 2.2 mrad turn), the least-squares quadratic
    # over five by 0.15.
    times = np.arange(12) * 0.1
    xi = np.array([0.0, 0.0, 0.3, 5.0, 0.0, 0.0])
    M = np.array([se3_exp((t + 0.05) * xi) for t in times])
    yaw = np.eye(4)
    yaw[:2, :2] = [[np.cos(1e-3), -np.sin(1e-3)], [np.sin(1e-3), np.cos(1e-3)]]
    M[1] = M[1] @ yaw
    M = invert_transform(M[0])[None] @ M
    results: list[RelativePose | None] = [None] + [
        RelativePose(invert_transform(M[k - 1]) @ M[k], None, prev=k - 1, curr=k)
        for k in range(1, 12)
    ]
    run = OdometryRun(M, times + 0.05, results, np.ones(12, int), [[] for _ in times])
    out = at_epoch_times(run, times, order=3)
    T = np.array([se3_exp(t * xi) for t in times])
    err = invert_transform(T[-1]) @ out.poses[-1]  # far from the perturbed node
    turn = np.arctan2(err[1, 0], err[0, 0])
    assert abs(turn) < 2.5e-4


def test_middle_timed_centres_each_scan_on_its_sweep():
    pts = np.zeros((3, 3))
    scans = [
        Scan(pts, None, np.array([0.0, 0.04, 0.1])),
        Scan(pts, None, np.array([0.02, 0.06, 0.1])),
    ]
    mid = MiddleTimed(scans, np.array([1.0, 1.1]))
    assert len(mid) == 2
    first = mid[0]
    assert isinstance(first, Scan) and first.t is not None
    assert np.allclose(first.t, [-0.05, -0.01, 0.05])
    assert np.isclose(mid.times[0], 1.05)
    second = mid[1]
    assert isinstance(second, Scan) and second.t is not None
    assert np.allclose(second.t, [-0.04, 0.0, 0.04]) and np.isclose(mid.times[1], 1.16)
    still = MiddleTimed([Scan(pts, None, None)], np.array([0.0]))
    assert still[0] is not None and mid.offsets.shape == (2,) and still.times[0] == 0.0


def _rotation_rms_deg(run, sim) -> float:
    gt = invert_transform(sim.poses[0])[None] @ sim.poses
    err = per_epoch_errors(relative_motions(run.poses), relative_motions(gt))
    rot = np.sqrt(err["roll"] ** 2 + err["pitch"] ** 2 + err["yaw"] ** 2)
    return float(np.degrees(np.sqrt(np.mean(rot**2))))


def test_middle_reference_on_a_continuous_lidar_run_is_closer_to_the_truth():
    sim = simulate_named("urban-canyon", "lidar32", noise=0.0, seed=1, n_epochs=12,
                         motion="continuous")  # fmt: skip
    base = PlanodomConfig().updated({"planemap.reference_time": "epoch"})
    middle = PlanodomConfig().updated({"planemap.reference_time": "middle"})
    at_start = run_odometry(sim.scans, base, sim.rig, times=sim.times)
    at_middle = run_odometry(sim.scans, middle, sim.rig, times=sim.times)
    assert at_middle.statuses[1:] == ["ok"] * 11
    assert np.allclose(at_middle.times, sim.times)
    assert _rotation_rms_deg(at_middle, sim) < 0.5 * _rotation_rms_deg(at_start, sim)


def test_centred_times_tells_a_sweep_registered_at_its_middle():
    from planodom.odometry.deskew import centred_times

    pts = np.zeros((3, 3))
    assert not centred_times(Scan(pts, None, np.array([0.0, 0.05, 0.1])))
    assert centred_times(Scan(pts, None, np.array([-0.05, 0.0, 0.0499])))
    assert not centred_times(Scan(pts, None, None))


def _yaw_pose(yaw: float) -> np.ndarray:
    T = np.eye(4)
    T[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
    return T


def test_first_pose_fits_reproduce_the_polynomials_of_their_degree():
    # a turn about one axis: the tangent at any node is the yaw difference, so a yaw
    # polynomial of the fit's degree is extrapolated exactly (closed form at t = 0)
    middles = 0.05 + 0.1 * np.arange(8)
    cubic = lambda t: 0.3 * t - 2.0 * t**2 + 4.0 * t**3  # noqa: E731
    quadratic = lambda t: 0.3 * t - 2.0 * t**2  # noqa: E731
    for fit, yaw, exact in [("cubic", cubic, True), ("quadratic", quadratic, True),
                            ("quadratic_fit", quadratic, True), ("quadratic", cubic, False),
                            ("quadratic_fit", cubic, False)]:  # fmt: skip
        poses = np.array([_yaw_pose(yaw(t)) for t in middles])
        got = first_pose(middles, poses, 0.0, fit)
        error = abs(np.arctan2(got[1, 0], got[0, 0]) - yaw(0.0))
        assert (error < 1e-12) == exact, (fit, error)


def test_first_pose_on_a_swing_the_cubic_is_closest():
    # a hand-held swing: yaw 10 deg at 1.45 Hz sampled at the middles of 10 Hz sweeps;
    # closed-form truth at the first epoch time (t = 0), rms over the swing's phase
    middles = 0.05 + 0.1 * np.arange(8)
    rms = {}
    for fit in ("quadratic_fit", "quadratic", "cubic"):
        errors = []
        for phase in np.linspace(0.0, 2 * np.pi, 16, endpoint=False):
            yaw = np.radians(10.0) * np.sin(2 * np.pi * 1.45 * middles + phase)
            got = first_pose(middles, np.array([_yaw_pose(y) for y in yaw]), 0.0, fit)
            errors.append(np.arctan2(got[1, 0], got[0, 0]) - np.radians(10.0) * np.sin(phase))
        rms[fit] = np.degrees(np.sqrt(np.mean(np.square(errors))))
    assert rms["cubic"] < rms["quadratic"] < rms["quadratic_fit"]


def test_at_epoch_times_takes_the_first_pose_fit_given():
    times = np.arange(8) * 0.1
    yaw = lambda t: 0.3 * t - 2.0 * t**2 + 4.0 * t**3  # noqa: E731
    M = np.array([_yaw_pose(yaw(t + 0.05)) for t in times])
    M = invert_transform(M[0])[None] @ M
    results: list[RelativePose | None] = [None] + [
        RelativePose(invert_transform(M[k - 1]) @ M[k], None, prev=k - 1, curr=k)
        for k in range(1, 8)
    ]
    run = OdometryRun(M, times + 0.05, results, np.ones(8, int), [[] for _ in times])
    out = at_epoch_times(run, times, order=3, first="cubic")
    # the first step from the exact first pose: the yaw from t = 0 to t = 0.1
    step = out.results[1]
    assert step is not None
    turn = np.arctan2(step.T_prev_curr[1, 0], step.T_prev_curr[0, 0])
    assert abs(turn - (yaw(0.1) - yaw(0.0))) < 1e-9
    with pytest.raises(ConfigError):
        PlanodomConfig().updated({"planemap.first_pose": "quartic"})
    assert PlanodomConfig().updated({"planemap.first_pose": "cubic"}).planemap.first_pose == "cubic"


def _sway(t: np.ndarray) -> np.ndarray:
    """(N, 6) tangents at the first middle: roll and pitch cubic, yaw and translation
    quadratic in ``t`` (s)."""
    t = np.asarray(t)[:, None]
    return (
        np.array([0.01, -0.02, 0.3, 5.0, 0.2, 0.01]) * t
        + np.array([-0.3, 0.2, -1.0, 0.8, -0.5, 0.0]) * t**2
        + np.array([2.0, -1.5, 0.0, 0.0, 0.0, 0.0]) * t**3
    )


def test_first_pose_mixed_takes_roll_and_pitch_cubic_and_yaw_smooth():
    # poses A exp(xi(t)) in the chart of the fits' middle node A (the fourth middle),
    # xi's roll and pitch cubic, the rest quadratic: `mixed` (a cubic for roll and pitch,
    # a quadratic for the rest) extrapolates it exactly to t = 0, the quadratic fit does
    # not (roll and pitch); closed-form truth
    middles = 0.05 + 0.1 * np.arange(9)
    A = se3_exp(np.array([0.1, -0.05, 1.2, 3.0, -2.0, 0.5]))
    poses = np.array([A @ se3_exp(x) for x in _sway(middles - middles[3])])
    truth = A @ se3_exp(_sway(np.array([-middles[3]]))[0])
    for fit, exact in [("mixed", True), ("quadratic_fit", False)]:
        error = np.abs(invert_transform(truth) @ first_pose(middles, poses, 0.0, fit) - np.eye(4))
        assert (error.max() < 1e-9) == exact, (fit, error.max())
    # a node's yaw error reaches the first pose less than through the cubic: the sum of
    # the squared responses to each node's yaw (its noise gain), from the first pose's yaw
    gains = {}
    for fit in ("mixed", "cubic"):
        base = first_pose(middles, poses, 0.0, fit)
        response = []
        for j in range(len(middles)):
            moved = poses.copy()
            moved[j] = moved[j] @ se3_exp(np.array([0, 0, 1e-6, 0, 0, 0]))
            got = invert_transform(base) @ first_pose(middles, moved, 0.0, fit)
            response.append(np.arctan2(got[1, 0], got[0, 0]) / 1e-6)
        gains[fit] = float(np.sum(np.square(response)))
    assert gains["mixed"] < 0.5 * gains["cubic"], gains
