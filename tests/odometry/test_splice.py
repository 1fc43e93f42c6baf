"""The deskewing passes' result kept where it converged, the streaming pass's elsewhere
(planodom.odometry.splice), on runs built from known steps."""

from dataclasses import replace

import numpy as np

from planodom.config import PlanodomConfig
from planodom.geometry import se3_exp
from planodom.odometry import RelativePose, Status
from planodom.odometry.interpolate import curve_steps
from planodom.odometry.run import OdometryRun
from planodom.odometry.splice import consistent, spliced, unconverged

DT = 0.2


def _run(steps: np.ndarray, statuses: list[Status], tag: int, prev=None) -> OdometryRun:
    """A run of the given steps (N - 1, 4, 4) from identity; epoch k's planes are the
    marker list ``[tag, k]`` (not planes: only their identity is compared)."""
    n = len(steps) + 1
    poses = [np.eye(4)]
    for s in steps:
        poses.append(poses[-1] @ s)
    prev = prev or [k - 1 for k in range(n)]
    results = [None] + [
        RelativePose(steps[k - 1], None, statuses[k], prev=prev[k], curr=k) for k in range(1, n)
    ]
    planes = [[tag, k] for k in range(n)]
    return OdometryRun(np.array(poses), DT * np.arange(n), results, np.full(n, tag), planes)


def _steps(twists: np.ndarray) -> np.ndarray:
    return se3_exp(np.asarray(twists, dtype=float) * DT)


def test_spliced_chains_each_epochs_step_from_its_own_run():
    """Poses chained from the steps of the run each epoch is taken from (compared with the
    product of the chosen steps written out), results / planes / counts from that run,
    and the epochs whose reference comes from the other run superseded."""
    rng = np.random.default_rng(3)
    a_steps, b_steps = _steps(rng.normal(size=(5, 6))), _steps(rng.normal(size=(5, 6)))
    ok = [Status.OK] * 6
    streaming, passes = _run(a_steps, ok, 1), _run(b_steps, ok, 2)
    passes.superseded = [5]
    keep = np.array([False, False, True, True, False, False])
    out = spliced(streaming, passes, keep)
    chosen = [b_steps[0], a_steps[1], a_steps[2], b_steps[3], b_steps[4]]
    expected = np.eye(4)
    for k, s in enumerate(chosen, start=1):
        expected = expected @ s
        np.testing.assert_allclose(out.poses[k], expected, atol=1e-12)
    assert [p[0] for p in out.planes] == [2, 2, 1, 1, 2, 2]
    assert list(out.n_planes) == [2, 2, 1, 1, 2, 2]
    assert out.results[2] is streaming.results[2] and out.results[4] is passes.results[4]
    # 2: its reference (1) is the passes'; 4: its reference (3) the streaming's; 5: its own
    assert out.superseded == [2, 4, 5]
    assert spliced(streaming, passes, np.zeros(6, bool)) is passes


def test_unconverged_where_the_step_leaves_the_curve_beyond_the_tolerances():
    """A step off the curve's by 0.6 deg/s in rotation (tolerance 0.5) is kept from the
    streaming pass, 0.4 deg/s is not; 0.6 m/s in translation (tolerance 0.5) is kept,
    0.4 m/s is not; an epoch not deskewed along the curve, a newly unresolved one and one
    degenerate where the streaming pass's is OK are kept, as is a degenerate one before
    the pass's first OK step."""
    cfg = PlanodomConfig()
    rng = np.random.default_rng(4)
    twists = rng.normal(scale=0.3, size=(7, 6))
    curve = _steps(twists)
    off = twists.copy()
    off[1, 2] += np.radians(0.6)  # epoch 2: rotation rate off by 0.6 deg/s
    off[2, 0] += np.radians(0.4)  # epoch 3: 0.4 deg/s, within the tolerance
    off[3, 3] += 0.6  # epoch 4: 0.6 m/s, the pass's step OK
    off[4, 4] += 0.4  # epoch 5: 0.4 m/s, within the tolerance
    statuses = [Status.OK] * 8
    statuses[1] = Status.DEGENERATE
    statuses[7] = Status.UNRESOLVED
    passes = _run(_steps(off), statuses, 2)
    streaming_statuses = [Status.OK] * 8
    streaming_statuses[5] = Status.DEGENERATE
    streaming = _run(curve, streaming_statuses, 1)
    deskewed = np.ones(8, bool)
    deskewed[6] = False
    keep = unconverged(streaming, passes, curve, deskewed, cfg)
    assert list(np.flatnonzero(keep)) == [1, 2, 4, 6, 7]

    def kept() -> list[int]:
        return list(np.flatnonzero(unconverged(streaming, passes, curve, deskewed, cfg)))

    # unresolved in both runs: nothing to gain from the streaming estimate
    streaming.results[7] = passes.results[7]
    assert kept() == [
        1,
        2,
        4,
        6,
    ]
    # degenerate in both: kept before the pass's first OK step (1), not after it (3)
    streaming.results[1] = passes.results[1]
    passes.results[3] = replace(passes.results[3], status=Status.DEGENERATE)
    streaming.results[3] = passes.results[3]
    assert kept() == [
        1,
        2,
        4,
        6,
    ]
    passes.results[1] = replace(passes.results[1], status=Status.OK)
    assert kept() == [2, 4, 6]


def test_curve_steps_of_nodes_on_a_constant_twist_are_that_twist():
    """Nodes on a constant-twist motion (a cubic reproduces it): every step between the
    query times is exp(twist dt), including beyond the nodes (extrapolated)."""
    twist = np.array([0.01, -0.02, 0.3, 1.5, 0.2, -0.1])
    node_times = 0.1 * np.arange(8) + 0.05
    nodes = se3_exp(twist[None] * node_times[:, None])
    times = 0.1 * np.arange(9)
    steps = curve_steps(node_times, nodes, times)
    np.testing.assert_allclose(steps, np.tile(se3_exp(twist * 0.1), (8, 1, 1)), atol=1e-9)


def test_consistent_splice_leaves_no_epochs_own_error_behind():
    """Ground truth: a straight drive at 1 m/s. The streaming run places epoch 3 with its
    own yaw error e (its steps 3 and 4: +e and -e), the pass places every epoch right.
    The guard keeps steps 2-3 from the streaming run (its epoch 3 error enters step 3)
    and takes the pass's step 4: the plain splice ends e off in yaw; the consistent one
    takes steps 3 and 4 from the pass (epoch 3 is placed differently by the two runs), so
    it ends on the truth, with step 2 (where the runs agree) still the streaming run's."""
    e = np.radians(1.0)  # 5 deg/s over a 0.2 s step: beyond the 0.5 deg/s tolerance
    n = 7
    truth = np.zeros((n - 1, 6))
    truth[:, 3] = 1.0  # twist: (rotation, translation) per second
    b_steps = _steps(truth)
    a_twists = truth.copy()
    a_twists[2, 2] += e / DT  # step 3 (0-based row 2): +e
    a_twists[3, 2] -= e / DT  # step 4: -e
    a_steps = _steps(a_twists)
    ok = [Status.OK] * n
    streaming, passes = _run(a_steps, ok, 1), _run(b_steps, ok, 2)
    keep = np.array([False, False, True, True, False, False, False])
    cfg = PlanodomConfig()
    plain = spliced(streaming, passes, keep)
    yaw = np.arctan2(plain.poses[-1][1, 0], plain.poses[-1][0, 0])
    np.testing.assert_allclose(yaw, e, atol=1e-9)  # the plain splice keeps e
    kept = consistent(streaming, passes, keep, cfg)
    assert list(np.flatnonzero(kept)) == [2]
    out = spliced(streaming, passes, kept)
    truth_poses = _run(b_steps, ok, 0).poses
    np.testing.assert_allclose(out.poses, truth_poses, atol=1e-9)


def test_consistent_keeps_a_switch_where_the_runs_differ_without_cancelling():
    """A streaming step off by a drift (not an epoch's own error: its next step is right)
    at the switch is no placement difference: the guard's keep is returned unchanged,
    and an epoch's own error below the tolerance does not move a switch either."""
    n = 7
    truth = np.zeros((n - 1, 6))
    truth[:, 3] = 1.0
    a_twists = truth.copy()
    a_twists[3, 2] += np.radians(2.0) / DT  # step 4 off, step 5 right: no cancelling pair
    a_twists[1, 2] += np.radians(0.05) / DT  # epoch 2's own error, 0.25 deg/s: below
    a_twists[2, 2] -= np.radians(0.05) / DT
    ok = [Status.OK] * n
    streaming, passes = _run(_steps(a_twists), ok, 1), _run(_steps(truth), ok, 2)
    keep = np.array([False, False, False, True, True, False, False])  # switches at 2 and 4
    kept = consistent(streaming, passes, keep, PlanodomConfig())
    np.testing.assert_array_equal(kept, keep)
