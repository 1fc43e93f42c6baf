"""The first epoch extracted again once its motion is known (:mod:`planodom.odometry.
first_epoch`, ``odometry.first_epoch_reextract``)."""

from __future__ import annotations

import numpy as np
import pytest
from planes_factory import observe, world_planes

from planodom.config import PlanodomConfig
from planodom.extraction import extract_planes
from planodom.geometry import invert_transform, se3_exp, se3_log
from planodom.odometry import PlaneOdometry, RelativePose, Status, run_odometry
from planodom.odometry.deskew import EpochEstimate
from planodom.odometry.first_epoch import first_twist, reextracted_first
from planodom.planes import PlaneSet
from planodom.scan import Scan
from planodom.simulation import simulate_named

DT = 0.1
TWIST = np.array([0.01, -0.02, 0.3, 4.0, 0.2, 0.05])


def estimate(status: Status, twist: np.ndarray = TWIST, prev: int = 0) -> EpochEstimate:
    """An estimate of the second epoch whose step has the twist ``twist`` over ``DT``."""
    relative = RelativePose(se3_exp(twist * DT), None, status, prev=prev, curr=1)
    return EpochEstimate([], PlaneSet.from_planes([]), None, relative, relative.T_prev_curr, [])


class First:
    def __init__(self, twist: np.ndarray | None = None):
        self.scan = Scan(np.zeros((2, 3)), t=[0.0, 0.05])
        self.twist = twist


def test_the_first_epochs_twist_is_what_the_step_measured():
    used = np.array([0.0, 0.0, 0.1, 1.0, 2.0, 3.0])
    np.testing.assert_allclose(first_twist(estimate(Status.OK), DT, None), TWIST, atol=1e-12)
    # degenerate: the step's angular rate, the velocity the first epoch was deskewed with
    got = first_twist(estimate(Status.DEGENERATE), DT, used)
    np.testing.assert_allclose(got, np.r_[TWIST[:3], used[3:]], atol=1e-12)
    assert first_twist(estimate(Status.DEGENERATE), DT, None) is None  # no velocity known
    assert first_twist(estimate(Status.UNRESOLVED), DT, used) is None
    assert first_twist(estimate(Status.OK), 0.0, used) is None


@pytest.mark.parametrize(
    ("statuses", "kept", "undone"),
    [
        ([Status.OK, Status.OK, Status.OK], 3, 0),  # every round kept
        ([Status.OK, Status.DEGENERATE], 1, 1),  # the second is worse: brought back
        ([Status.UNRESOLVED], 0, 1),  # no longer measured
    ],
)
def test_rounds_are_kept_while_the_step_is_no_worse(statuses, kept, undone):
    first, calls, undos = First(), [], []
    config = PlanodomConfig().odometry.model_copy(update={"first_epoch_reextract": 3})

    def round_(twist, best):
        calls.append(twist)
        first.twist = twist  # the first epoch's planes are now deskewed with it
        k = len(calls)
        return estimate(statuses[k - 1], TWIST * (1 + 0.1 * k)), lambda: undos.append(k)

    best = estimate(Status.OK)
    out = reextracted_first(best, DT, config, first, round_)
    assert len(calls) == len(statuses) and len(undos) == undone
    assert out.relative.status is (statuses[kept - 1] if kept else Status.OK)
    np.testing.assert_allclose(calls[0], TWIST, atol=1e-12)  # the step's own twist first
    if kept:
        np.testing.assert_allclose(se3_log(out.step) / DT, TWIST * (1 + 0.1 * kept), atol=1e-9)


def test_no_round_without_point_times_or_from_another_epoch():
    config = PlanodomConfig().odometry.model_copy(update={"first_epoch_reextract": 3})
    first = First()
    first.scan = Scan(np.zeros((2, 3)))  # no point times

    def never(twist, best):
        raise AssertionError("no round expected")

    best = estimate(Status.OK)
    assert reextracted_first(best, DT, config, first, never) is best
    other = estimate(Status.OK, prev=-1)  # estimated against another epoch
    assert reextracted_first(other, DT, config, First(), never) is other


def test_a_scan_sequence_without_point_times_is_unchanged():
    """Without point times nothing is deskewed: the rounds change nothing, and the first
    epoch is extracted once."""
    world = world_planes(np.random.default_rng(3), 8)
    poses = [se3_exp(TWIST * DT * k) for k in range(4)]
    planes = [observe(world, T) for T in poses]

    def run(rounds: int) -> tuple[PlaneOdometry, list[tuple[int, bool]]]:
        calls: list[tuple[int, bool]] = []

        def extractor(scan, cfg, twist=None):
            k = int(scan.points[0, 0])
            calls.append((k, twist is not None))
            return planes[k]

        cfg = PlanodomConfig().updated(
            {"odometry.pipeline": "wocsc", "odometry.first_epoch_reextract": rounds}
        )
        odo = PlaneOdometry(cfg, extractor=extractor)
        for k in range(4):
            odo.register_epoch(Scan(np.full((2, 3), float(k))), DT * k)
        return odo, calls

    (off, calls_off), (on, calls_on) = run(0), run(3)
    assert calls_on == calls_off and calls_on.count((0, False)) == 1
    for a, b, T in zip(off.poses, on.poses, poses, strict=True):
        np.testing.assert_array_equal(a, b)
        np.testing.assert_allclose(b, T, atol=1e-9)


def plane_offsets(planes, scene, T_world_base: np.ndarray) -> np.ndarray:
    """(K,) distance (m) of each plane's inlier centroid to its true surface, seen from
    ``T_world_base``."""
    R, t = T_world_base[:3, :3], T_world_base[:3, 3]
    out = []
    for p in planes:
        s = scene.by_id(p.truth_id)
        n, d = R.T @ s.normal, s.offset + s.normal @ t
        out.append(abs(n @ p.support.centroid + d))
    return np.array(out)


def test_a_run_starting_at_speed_gets_first_planes_near_the_true_surfaces():
    """A lidar starting at 8 m/s on the simulated paper loop (sigma = 0): the first
    epoch's points are smeared by 0.8 m over the sweep. With the rounds its planes come
    near the true surfaces (compared with the simulator's, seen from the first pose), far
    nearer than extracted without a twist, and its twist near the true twist of the
    first step."""
    run = simulate_named("paper-loop", "lidar16", noise=0.0, seed=1, n_epochs=3, speed=8.0)
    cfg = PlanodomConfig().updated(
        {"odometry.pipeline": "wocsc", "odometry.first_epoch_reextract": 3}
    )
    odo = run_odometry(run, cfg, run.rig)
    first = [p for p in odo.planes[0] if p.truth_id >= 0]
    raw = [p for p in extract_planes(run.scans[0], cfg.extraction) if p.truth_id >= 0]
    got = plane_offsets(first, run.scene, run.poses[0])
    smeared = plane_offsets(raw, run.scene, run.poses[0])
    assert len(first) >= len(raw) - 1
    assert np.median(got) < 0.01 and np.median(got) < 0.3 * np.median(smeared)
    # the step the rounds end with: its twist within 0.01 rad/s and 0.05 m/s of the truth
    true = se3_log(invert_transform(run.poses[0]) @ run.poses[1]) / DT
    own = se3_log(odo.poses[1]) / DT
    assert np.linalg.norm(own[:3] - true[:3]) < 0.01
    assert np.linalg.norm(own[3:] - true[3:]) < 0.05
    off = run_odometry(run, cfg.updated({"odometry.first_epoch_reextract": 0}), run.rig)
    before = [p.offset for p in off.planes[0]]
    assert len(before) != len(odo.planes[0]) or not np.allclose(
        before, [p.offset for p in odo.planes[0]], atol=1e-9, rtol=0
    )  # the rounds did extract it again
