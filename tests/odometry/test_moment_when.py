"""Which estimates the moments refine (planodom.odometry.moment_when)."""

import numpy as np

from planodom.config import PlanodomConfig
from planodom.geometry import invert_transform, se3_exp, se3_log
from planodom.odometry.deskew import EpochEstimate
from planodom.odometry.moment_when import refined_commit, refined_estimate, settled
from planodom.odometry.odometry import PlaneOdometry
from planodom.odometry.relative import RelativePose, Status
from planodom.planes import PlaneSet
from tests.odometry.test_moment_refine import _epochs

IJ = np.array([[0, 0], [1, 1], [2, 2], [3, 3]])
MOMENTS = {"odometry.refinement": "moments"}


def _odometry(statuses: list[Status], gaps: set[int] = frozenset(), **changes) -> PlaneOdometry:
    """An odometry whose epochs 1 .. len(statuses) have results of these statuses."""
    odo_changes = {f"odometry.{k}": v for k, v in changes.items()}
    config = PlanodomConfig().updated({**MOMENTS, **odo_changes}, source="t")
    odo = PlaneOdometry(config)
    odo.results = [None] + [RelativePose(np.eye(4), None, s, IJ) for s in statuses]
    odo._gaps = set(gaps)
    return odo


def test_every_step_is_settled_without_the_guard():
    assert settled(_odometry([]), 1)
    assert settled(_odometry([Status.UNRESOLVED]), 2)


def test_the_guard_waits_for_n_ok_steps_after_a_start_a_gap_or_a_lost_step():
    ok, lost = Status.OK, Status.UNRESOLVED
    # the start: epochs 1 .. 3 have fewer than three steps before them
    assert [settled(_odometry([ok] * 5, moment_after_ok=3), k) for k in range(1, 7)] == [
        False, False, False, True, True, True,
    ]  # fmt: skip
    # an unresolved (or degenerate) step 4: epochs 5, 6, 7 wait, 8 is refined again
    statuses = [ok, ok, ok, lost, ok, ok, ok, ok]
    want = [True, False, False, False, True]
    assert [settled(_odometry(statuses, moment_after_ok=3), k) for k in range(4, 9)] == want
    statuses[3] = Status.DEGENERATE
    assert [settled(_odometry(statuses, moment_after_ok=3), k) for k in range(4, 9)] == want
    # epoch 6 follows a gap in the epoch times: 6, 7, 8 wait although every step is OK
    gapped = _odometry([ok] * 9, gaps={6}, moment_after_ok=3)
    assert [settled(gapped, k) for k in range(5, 11)] == [True, False, False, False, True, True]


def _estimate(start: np.ndarray, status: Status = Status.OK):
    """An estimate of the :mod:`test_moment_refine` planes at ``start`` (T_prev_curr), its
    step ``T_{k-1}_ref @ start`` with a known ``T_{k-1}_ref``, and that transform."""
    truth = se3_exp(np.array([0.002, -0.001, 0.03, 0.8, 0.05, 0.01]))
    prev, curr = _epochs(truth)
    T_last_ref = se3_exp(np.array([0.001, 0.0, -0.02, -0.7, 0.02, 0.0]))
    relative = RelativePose(start @ np.eye(4), None, status, IJ, prev=3, curr=5)
    est = EpochEstimate(curr, PlaneSet.from_planes(curr), None, relative, T_last_ref @ start, prev)
    return est, truth, T_last_ref


def test_a_committed_estimate_is_refined_to_the_truth_and_its_step_moves_with_it():
    truth = se3_exp(np.array([0.002, -0.001, 0.03, 0.8, 0.05, 0.01]))
    start = truth @ se3_exp(np.array([0.004, 0.003, -0.01, 0.03, -0.04, 0.02]))
    est, truth, T_last_ref = _estimate(start)
    odo = _odometry([Status.OK] * 4, moment_extractions="committed")
    out = refined_commit(odo, est, 5)
    assert np.abs(se3_log(invert_transform(truth) @ out.relative.T_prev_curr)).max() < 1e-8
    assert np.abs(se3_log(invert_transform(T_last_ref @ truth) @ out.step)).max() < 1e-8
    assert (out.relative.prev, out.relative.curr) == (3, 5) and out.planes is est.planes
    # the extraction's own estimate is not refined under "committed"
    assert refined_estimate(odo, est.relative, est.reference_planes, 5, est.planes, None) is (
        est.relative
    )


def test_a_commit_is_left_alone_when_all_are_refined_unsettled_or_not_ok():
    truth = se3_exp(np.array([0.002, -0.001, 0.03, 0.8, 0.05, 0.01]))
    start = truth @ se3_exp(np.array([0.004, 0.003, -0.01, 0.03, -0.04, 0.02]))
    est, _, _ = _estimate(start)
    assert refined_commit(_odometry([Status.OK] * 4), est, 5) is est  # "all": done before
    guarded = _odometry([Status.OK] * 4, moment_extractions="committed", moment_after_ok=5)
    assert refined_commit(guarded, est, 5) is est
    degenerate, _, _ = _estimate(start, Status.DEGENERATE)
    odo = _odometry([Status.OK] * 4, moment_extractions="committed")
    assert refined_commit(odo, degenerate, 5) is degenerate
    committed = {"odometry.moment_extractions": "committed"}
    off = PlaneOdometry(PlanodomConfig().updated(committed, source="t"))
    assert refined_commit(off, est, 5) is est  # refinement: translation (the default)


def test_every_extraction_is_refined_by_default_once_settled():
    truth = se3_exp(np.array([0.002, -0.001, 0.03, 0.8, 0.05, 0.01]))
    start = truth @ se3_exp(np.array([0.004, 0.003, -0.01, 0.03, -0.04, 0.02]))
    est, truth, _ = _estimate(start)
    args = (est.relative, est.reference_planes, 1, est.planes, None)
    refined = refined_estimate(_odometry([]), *args)
    assert np.abs(se3_log(invert_transform(truth) @ refined.T_prev_curr)).max() < 1e-8
    early = _odometry([Status.OK], moment_after_ok=2)
    assert refined_estimate(early, est.relative, est.reference_planes, 2, est.planes, None) is (
        est.relative
    )
