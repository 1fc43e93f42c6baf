"""A vehicle's start deskewed with its first degenerate steps' yaw rate and forward speed
(planodom.odometry.vehicle_start, ``odometry.start_vehicle_twist``)."""

from __future__ import annotations

import numpy as np

from planodom.geometry import Plane, se3_exp
from planodom.odometry.deskew import EpochEstimate
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.vehicle_start import vehicle_twist
from planodom.planes import PlaneSet

DT = 0.1
SIN_15 = float(np.sin(np.radians(15.0)))


def _degenerate(true_twist: np.ndarray, wall_yaw_deg: float) -> EpochEstimate:
    """A degenerate step over ``DT`` s of the constant body twist ``true_twist`` (6,) as
    a plane solver with a standing-still prior gives it from the ground and one wall
    (normal at ``wall_yaw_deg`` from the base x): the rotation right, the translation
    along the direction the two normals leave unmeasured zero."""
    T = se3_exp(true_twist * DT)
    a = np.radians(wall_yaw_deg)
    normals = np.array([[0.0, 0.0, 1.0], [np.cos(a), np.sin(a), 0.0]])
    u = np.cross(normals[0], normals[1])
    u /= np.linalg.norm(u)
    T[:3, 3] -= (u @ T[:3, 3]) * u  # the prior's (zero) translation along u
    planes = [Plane(n, -1.0) for n in normals]
    relative = RelativePose(T, None, Status.DEGENERATE, np.array([[0, 0], [1, 1]]))
    return EpochEstimate(planes, PlaneSet.from_planes(planes), None, relative, T, planes)


def test_the_speed_is_solved_on_the_arc():
    """A vehicle's twist (yaw rate 0.27 rad/s, 3.74 m/s along x: world 190's start) seen
    through the ground and a wall 55 deg off the track: the step lost a third of its
    along-track translation to the prior; the vehicle's twist is the true one again (the
    arc constraint is exact for a constant twist without lateral velocity)."""
    truth = np.array([0.0, 0.0, 0.27, 3.74, 0.0, 0.0])
    est = _degenerate(truth, 55.0)
    assert abs(est.own_twist(DT)[3] - 3.74) > 0.5  # what the step alone says
    got = vehicle_twist(est, DT, SIN_15)
    assert got is not None
    np.testing.assert_allclose(got, truth, atol=1e-9)


def test_roll_and_pitch_rates_are_dropped():
    """The true twist with a roll and pitch rate (a vehicle's suspension): the vehicle's
    twist keeps the yaw rate and the forward speed (to first order in the small rates)."""
    truth = np.array([0.03, -0.02, 0.27, 3.74, 0.0, 0.0])
    got = vehicle_twist(_degenerate(truth, 55.0), DT, SIN_15)
    assert got is not None
    assert got[0] == got[1] == got[4] == got[5] == 0.0
    assert abs(got[2] - 0.27) < 2e-3 and abs(got[3] - 3.74) < 0.02


def test_a_wall_along_the_track_measures_no_speed():
    """The wall's normal across the track (its line along it): the unmeasured direction is
    the track's own, the arc does not fix the speed, and no twist is made."""
    truth = np.array([0.0, 0.0, 0.27, 3.74, 0.0, 0.0])
    assert vehicle_twist(_degenerate(truth, 90.0), DT, SIN_15) is None
    assert vehicle_twist(_degenerate(truth, 80.0), DT, SIN_15) is None


class _Ref:
    def __init__(self):
        self.index, self.scan, self.planes = 4, "scan4", ["old"]
        self.twist, self.plane_set = None, None

    def has_pair(self, _association) -> bool:
        return True


class _FakeOdometry:
    """What :func:`vehicle_started` uses of the odometry: the reference, its extraction
    and the epoch's estimate with a twist (status ``status_again``)."""

    def __init__(self, on: bool, gated: EpochEstimate, status_again: Status):
        from planodom.config import PlanodomConfig

        self.config = PlanodomConfig().updated({"odometry.start_vehicle_twist": on})
        self._map, self._rates, self.times = None, [], [0.4]
        self._twist_sigma = type("S", (), {"ungated": [gated]})()
        self.ref, self._last_usable, self.results, self.superseded = _Ref(), None, {4: 1}, set()
        self.status_again, self.extracted = status_again, []

    def _reference(self):
        return self.ref

    def _set_planes(self, ref, planes, twist, plane_set=None):
        ref.planes, ref.twist = planes, twist

    def _extract(self, scan, twist):
        self.extracted.append((scan, twist))
        return ["new"], twist

    def _estimate_scan(self, scan, t, twist):
        relative = RelativePose(np.eye(4), None, self.status_again)
        return EpochEstimate([], PlaneSet.from_planes([]), twist, relative, np.eye(4), [])


def _gated_best() -> tuple[EpochEstimate, EpochEstimate]:
    """A degenerate step (world 190's start) and the same reported unresolved by the gate."""
    from dataclasses import replace

    ungated = _degenerate(np.array([0.0, 0.0, 0.27, 3.74, 0.0, 0.0]), 55.0)
    relative = replace(ungated.relative, status=Status.UNRESOLVED, inconsistent=True)
    return ungated, replace(ungated, relative=relative)


def test_kept_only_when_ok_else_the_reference_comes_back():
    from planodom.odometry.vehicle_start import vehicle_started

    ungated, best = _gated_best()
    odo = _FakeOdometry(False, ungated, Status.OK)  # the option off: nothing is done
    assert vehicle_started(odo, "scan5", 0.5, best) is best and not odo.extracted
    odo = _FakeOdometry(True, ungated, Status.DEGENERATE)  # not OK (and not gated): undone
    assert vehicle_started(odo, "scan5", 0.5, best) is best
    assert odo.ref.planes == ["old"] and odo.ref.twist is None and not odo.superseded
    assert len(odo.extracted) == 1
    np.testing.assert_allclose(odo.extracted[0][1], [0, 0, 0.27, 3.74, 0, 0], atol=1e-9)
    odo = _FakeOdometry(True, ungated, Status.OK)  # OK: kept, the reference's old step gone
    got = vehicle_started(odo, "scan5", 0.5, best)
    assert got.relative.status is Status.OK and odo.ref.planes == ["new"]
    assert odo.superseded == {4} and odo._last_usable is odo.ref
