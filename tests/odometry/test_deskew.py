"""The deskewing policy (planodom.odometry.deskew.register_deskewed) with a scripted
estimator: which extraction of an epoch is kept."""

from __future__ import annotations

import numpy as np

from planodom.config import PlanodomConfig
from planodom.geometry import Plane
from planodom.odometry.deskew import EpochEstimate, register_deskewed, with_deskew
from planodom.odometry.relative import RelativePose, Status
from planodom.planes import PlaneSet
from planodom.scan import Scan

HELD = np.array([0.0, 0.0, 0.1, 1.0, 0.0, 0.0])


def _estimate(twist: np.ndarray | None, status: Status, n_planes: int) -> EpochEstimate:
    planes = [Plane(np.array([0.0, 0.0, 1.0]), float(i)) for i in range(n_planes)]
    relative = RelativePose(np.eye(4), None, status)
    return EpochEstimate(planes, PlaneSet.from_planes(planes), twist, relative, np.eye(4), [])


def _scripted(outcomes: dict[str, tuple[Status, int]], calls: list[str]):
    def estimate(twist: np.ndarray | None, source: EpochEstimate | None = None) -> EpochEstimate:
        key = "none" if twist is None else ("held" if np.array_equal(twist, HELD) else "other")
        calls.append(key)
        return _estimate(twist, *outcomes[key])

    return estimate


def _register(outcomes, predicted, held, previous=4):
    calls: list[str] = []
    config = PlanodomConfig().odometry.model_copy(update={"deskew_iterations": 0})
    best = register_deskewed(
        predicted, 0.1, _scripted(outcomes, calls), lambda t: False, config, previous, held
    )
    return best, calls


def test_after_an_unresolved_epoch_the_held_twist_is_tried_when_the_plain_one_fails():
    outcomes = {"none": (Status.UNRESOLVED, 1), "held": (Status.OK, 4)}
    best, calls = _register(outcomes, None, HELD)
    assert calls == ["none", "held"]
    assert best.relative.status is Status.OK and np.array_equal(best.twist, HELD)


def test_the_held_twist_is_not_tried_when_the_plain_extraction_is_fine():
    outcomes = {"none": (Status.OK, 4), "held": (Status.OK, 6)}
    best, calls = _register(outcomes, None, HELD)
    assert calls == ["none"] and best.twist is None


def test_the_held_twist_is_dropped_when_it_does_no_better():
    outcomes = {"none": (Status.UNRESOLVED, 1), "held": (Status.UNRESOLVED, 1)}
    best, calls = _register(outcomes, None, HELD)
    assert calls == ["none", "held"] and best.twist is None


def test_a_predicted_twist_that_fails_is_replaced_by_no_deskewing():
    outcomes = {"held": (Status.UNRESOLVED, 0), "none": (Status.DEGENERATE, 3)}
    best, calls = _register(outcomes, HELD, None)
    assert calls == ["held", "none"]
    assert best.twist is None and best.relative.status is Status.DEGENERATE


def test_with_deskew_records_the_twist_its_times_and_the_interval():
    rel = RelativePose(np.eye(4), None, prev=3, curr=4)
    pts = np.zeros((4, 3))
    twist = np.array([0.1, 0.0, 0.2, 1.0, 0.0, 0.0])
    out = with_deskew(rel, Scan(points=pts, t=np.array([-0.05, 0.0, 0.02, 0.05])), twist, 0.1)
    assert out.time_spread and out.interval_s == 0.1
    assert out.deskew_times == (-0.05, 0.05)
    assert out.deskew_twist is not None and np.array_equal(out.deskew_twist, twist)
    assert out.deskew_twist is not twist  # a copy: the odometry's own twist may change
    instant = with_deskew(rel, Scan(points=pts, t=np.zeros(4)), twist, 0.1)
    assert instant.time_spread is False and instant.deskew_twist is None
    assert instant.deskew_times is None and instant.interval_s == 0.1
    undeskewed = with_deskew(rel, Scan(points=pts, t=np.array([0.0, 0.1, 0.2, 0.3])), None, 0.1)
    assert undeskewed.time_spread and undeskewed.deskew_twist is None
    assert undeskewed.deskew_times == (0.0, 0.3)  # the sandwich's error of not deskewing
