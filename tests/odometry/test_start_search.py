"""A vehicle's twist searched for an unresolved step at the start
(planodom.odometry.start_search, ``odometry.start_twist_search``)."""

from __future__ import annotations

import numpy as np

from planodom.config import PlanodomConfig
from planodom.geometry import se3_exp
from planodom.odometry.deskew import EpochEstimate
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.start_search import candidates, searched_start, vehicle_part
from planodom.planes import PlaneSet

DT = 0.1
#: a start in a turn (2D-rig world 292's: 36 deg/s of yaw at 4.5 m/s), with the small
#: roll and pitch rates and vertical velocity of a vehicle's sway
TRUTH = np.array([0.028, 0.016, 0.636, 4.526, 0.009, 0.065])
#: the yaw-rate (rad/s) and speed (m/s) errors of the deskewing twist the steps stay OK within
OK_WITHIN = np.array([np.radians(7.0), 1.0])
#: how much of the deskewing's yaw-rate and speed error a step's own twist keeps
BIAS = 0.3


def _estimate(status: Status, twist: np.ndarray | None, step_twist: np.ndarray) -> EpochEstimate:
    relative = RelativePose(se3_exp(step_twist * DT), None, status)
    return EpochEstimate([], PlaneSet.from_planes([]), twist, relative, relative.T_prev_curr, [])


class _Ref:
    def __init__(self):
        self.index, self.scan, self.planes = 0, "scan0", ["none"]
        self.twist, self.plane_set = None, "set0"

    def has_pair(self, _association) -> bool:
        return True


class _StartInATurn:
    """What :func:`searched_start` uses of the odometry, for a vehicle starting in a turn
    of the constant twist :data:`TRUTH`: an epoch (and its reference) deskewed with a
    twist whose yaw rate and speed are within :data:`OK_WITHIN` of the truth's gives an OK
    step (the twist's prediction its prior: ``twist`` is the candidate then), whose
    own twist keeps :data:`BIAS` of the deskewing twist's error in the yaw rate and the
    forward speed (a deskewing error moves the measured motion); else the step is
    unresolved, as without a twist."""

    def __init__(self, on: bool = True, truth: np.ndarray = TRUTH, rates: list | None = None):
        self.config = PlanodomConfig().updated({"odometry.start_twist_search": on})
        self._map, self._rates, self.times, self.poses = None, rates or [], [0.0], [np.eye(4)]
        self.ref, self._last_usable, self.results, self.superseded = _Ref(), None, [None], set()
        self.truth, self.extracted, self.twist, self.priors = truth, [], None, []

    def _reference(self):
        return self.ref

    def _set_planes(self, ref, planes, twist, plane_set=None):
        ref.planes, ref.twist, ref.plane_set = planes, twist, plane_set

    def _extract(self, scan, twist):
        self.extracted.append(np.array(twist))
        return [f"{scan} at {twist[2]:.4f}"], twist

    def _estimate_scan(self, scan, t, twist):
        self.priors.append(self.twist)
        if np.any(np.abs(twist[2:4] - self.truth[2:4]) > OK_WITHIN):
            return _estimate(Status.UNRESOLVED, twist, np.zeros(6))
        own = self.truth.copy()
        own[2:4] += BIAS * (twist[2:4] - self.truth[2:4])
        return _estimate(Status.OK, twist, own)


def _unresolved() -> EpochEstimate:
    return _estimate(Status.UNRESOLVED, None, np.zeros(6))


def test_the_candidates_are_a_vehicles_yaw_rates_and_speeds():
    got = np.array(candidates())
    assert got.shape == (48, 6) and not np.any(got[:, [0, 1, 4, 5]])
    rates = sorted({round(float(np.degrees(w)), 6) for w in got[:, 2]})
    assert rates == [*range(-60, 0, 10), *range(10, 70, 10)]
    assert sorted(set(got[:, 3])) == [1.5, 3.0, 4.5, 6.0]


def test_a_start_in_a_turn_finds_the_true_yaw_rate_and_speed():
    """The OK candidate whose step agrees with its deskewing is refined with the step's
    own yaw rate and forward speed: after the rounds the twist is the truth's yaw rate
    and speed to BIAS ** rounds of the first candidate's error, the other components of
    the vehicle's twist zero; the reference keeps the planes of that twist."""
    odo = _StartInATurn()
    best = _unresolved()
    got = searched_start(odo, "scan1", DT, best)
    assert got.relative.status is Status.OK
    rounds = odo.config.odometry.deskew_iterations
    first = np.array([np.radians(40.0), 4.5])  # the most consistent candidate
    bound = BIAS**rounds * np.abs(first - TRUTH[2:4]) + 1e-9
    assert np.all(np.abs(got.twist[2:4] - TRUTH[2:4]) <= bound)
    assert not np.any(got.twist[[0, 1, 4, 5]])
    assert odo.ref.twist is got.twist and odo.ref.planes == [f"scan0 at {got.twist[2]:.4f}"]
    assert odo._last_usable is odo.ref
    assert all(np.array_equal(p, u) for p, u in zip(odo.priors, odo.extracted, strict=True))
    assert odo.twist is None  # the odometry's prediction as it was


def test_a_turn_to_the_right_too():
    truth = TRUTH * np.array([1, 1, -1, 1, 1, 1])
    got = searched_start(_StartInATurn(truth=truth), "scan1", DT, _unresolved())
    assert got.relative.status is Status.OK and abs(got.twist[2] - truth[2]) < np.radians(1.0)


def test_no_ok_candidate_brings_the_reference_back():
    odo = _StartInATurn(truth=np.array([0.0, 0.0, np.radians(120.0), 4.0, 0.0, 0.0]))
    best = _unresolved()
    assert searched_start(odo, "scan1", DT, best) is best
    assert odo.ref.planes == ["none"] and odo.ref.twist is None and odo.ref.plane_set == "set0"
    assert len(odo.extracted) == len(candidates()) and odo._last_usable is None


def test_nothing_is_done_off_after_a_measured_rate_or_for_a_measured_step():
    for odo, best in [
        (_StartInATurn(on=False), _unresolved()),
        (_StartInATurn(rates=[(1, TRUTH)]), _unresolved()),
        (_StartInATurn(), _estimate(Status.DEGENERATE, None, TRUTH)),
    ]:
        assert searched_start(odo, "scan1", DT, best) is best and not odo.extracted


def test_the_vehicle_part_of_a_step():
    got = vehicle_part(_estimate(Status.OK, None, TRUTH), DT)
    np.testing.assert_allclose(got, [0, 0, TRUTH[2], TRUTH[3], 0, 0], atol=1e-12)
