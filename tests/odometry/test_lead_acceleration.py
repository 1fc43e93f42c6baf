"""A led epoch deskewed with its rate's change too (:mod:`planodom.odometry.lead_acceleration`,
``odometry.map_lead_acceleration``)."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import OdometryConfig
from planodom.extraction.deskew import deskew_points
from planodom.geometry import se3_exp
from planodom.odometry.kept_epoch import KeptEpoch
from planodom.odometry.lead_acceleration import (
    LeadAcceleration,
    accelerated_points,
    lead_acceleration,
)
from planodom.odometry.trend import Lead
from planodom.planes import PlaneSet
from planodom.scan import Scan

RNG = np.random.default_rng(7)
WORLD = RNG.uniform(-20.0, 20.0, (40, 3))  # fixed points, world = the reference frame
T = np.sort(RNG.uniform(-0.05, 0.05, 40))  # the points' times from the reference time
W0, ALPHA = 0.6, 9.0  # yaw rate (rad/s) at the reference time and its change (rad/s^2)
V = np.array([3.0, 0.2, -0.1])  # m/s, constant in the body frame


def _pose(t: float, n: int = 200) -> np.ndarray:
    """T_ref_base at ``t`` s: yaw rate W0 + ALPHA t and velocity V in the body frame, the
    product of many short steps from the identity at 0 (an independent integration)."""
    T_ = np.eye(4)
    h = t / n
    for i in range(n):
        T_ = T_ @ se3_exp(np.r_[0.0, 0.0, W0 + ALPHA * (i + 0.5) * h, V] * h)
    return T_


def _seen() -> np.ndarray:
    """(N, 3) each world point in the base frame of its time."""
    out = np.empty_like(WORLD)
    for i, (p, t) in enumerate(zip(WORLD, T, strict=True)):
        M = np.linalg.inv(_pose(float(t)))
        out[i] = M[:3, :3] @ p + M[:3, 3]
    return out


def test_points_rotate_by_the_acceleration_in_closed_form():
    """Each point is turned about the acceleration's axis by ``|alpha| t^2 / 2``: against
    the rotation matrix about z written out."""
    p = RNG.normal(size=(50, 3))
    t = RNG.uniform(-0.05, 0.05, 50)
    got = accelerated_points(p, t, np.array([0.0, 0.0, -4.0]))
    a = -4.0 * t**2 / 2
    want = np.c_[np.cos(a) * p[:, 0] - np.sin(a) * p[:, 1],
                 np.sin(a) * p[:, 0] + np.cos(a) * p[:, 1], p[:, 2]]  # fmt: skip
    np.testing.assert_allclose(got, want, atol=1e-14)
    np.testing.assert_array_equal(accelerated_points(p, t, np.zeros(3)), p)


def test_a_turn_that_tightens_is_deskewed_to_second_order():
    """Under a yaw rate changing linearly within the sweep, the constant twist at the
    reference time leaves the points |alpha| t^2 / 2 off (up to 0.1 mm x range here);
    rotated first by the change, they land on the world points to third order."""
    seen = _seen()
    twist = np.r_[0.0, 0.0, W0, V]
    plain = deskew_points(seen, T, twist)
    accel = deskew_points(accelerated_points(seen, T, np.array([0.0, 0.0, ALPHA])), T, twist)
    err_plain = np.linalg.norm(plain - WORLD, axis=1).max()
    err_accel = np.linalg.norm(accel - WORLD, axis=1).max()
    assert err_plain > 1e-3  # 9 rad/s^2 x 0.05^2 / 2 x 35 m: 0.4 m at the sweep's ends
    assert err_accel < 0.02 * err_plain


def _lead(var: np.ndarray | None = None) -> Lead:
    return Lead(np.array([0.0, 0.0, 0.5, np.nan, np.nan, np.nan]), 0.1, 0.2, 0.05, 3, var)


def test_only_this_epochs_scan_is_rotated_by_the_twists_change():
    """alpha is the rate's change from the previous epoch's kept twist over dt; another
    scan (a reference extracted again), a scan without times, or no twist: as it is."""
    scan = Scan(points=WORLD.copy(), t=T.copy())
    previous = np.array([0.0, 0.0, 0.5, 3.0, 0.0, 0.0])
    acc = LeadAcceleration(scan, previous, 0.1)
    twist = previous + np.r_[0.1, -0.2, 0.9, 1.0, 1.0, 1.0]
    got = acc.accelerated(scan, twist)
    want = accelerated_points(WORLD, T, np.array([1.0, -2.0, 9.0]))
    np.testing.assert_allclose(got.points, want, atol=1e-12)
    other = Scan(points=WORLD.copy(), t=T.copy())
    assert acc.accelerated(other, twist) is other
    assert acc.accelerated(scan, None) is scan
    untimed = Scan(points=WORLD.copy())
    assert LeadAcceleration(untimed, previous, 0.1).accelerated(untimed, twist) is untimed


def test_stated_shrinks_a_change_within_its_noise():
    """With ``stated`` each axis of the change is scaled by c^2 / (c^2 + 6.5 v): a change
    far beyond its noise is kept, one far within it is nearly dropped."""
    scan = Scan(points=WORLD.copy(), t=T.copy())
    previous = np.zeros(6)
    var = np.array([1e-12, 1e-12, 1e4])  # roll and pitch known well, yaw pure noise
    acc = LeadAcceleration(scan, previous, 0.1, var)
    twist = np.r_[0.2, 0.3, 0.4, 0.0, 0.0, 0.0]
    got = acc.accelerated(scan, twist).points
    gain = 0.4**2 / (0.4**2 + 6.5e4)
    want = accelerated_points(WORLD, T, np.array([2.0, 3.0, 4.0 * gain]))
    np.testing.assert_allclose(got, want, atol=1e-9)


def test_formed_only_when_on_and_the_rate_is_led():
    scan = Scan(points=WORLD.copy(), t=T.copy())
    kept = KeptEpoch(0, [], PlaneSet.from_planes([]), scan, np.r_[0.0, 0.0, 0.5, 3.0, 0, 0])
    on = OdometryConfig(map_lead_acceleration="rate")
    assert lead_acceleration(_lead(), scan, [kept], 0.1, OdometryConfig()) is None  # off
    assert lead_acceleration(None, scan, [kept], 0.1, on) is None  # not led
    unled = Lead(None, 0.0, 0.2, 0.05, 3)
    assert lead_acceleration(unled, scan, [kept], 0.1, on) is None  # no previous rate
    assert lead_acceleration(_lead(), scan, [], 0.1, on) is None
    got = lead_acceleration(_lead(np.ones(3)), scan, [kept], 0.1, on)
    assert got is not None and got.variance is None and got.dt == 0.1
    stated = OdometryConfig(map_lead_acceleration="stated")
    got = lead_acceleration(_lead(np.ones(3)), scan, [kept], 0.1, stated)
    assert got is not None and got.variance is not None


@pytest.mark.parametrize("value", ["on", "quadratic"])
def test_a_bad_value_names_file_and_field(tmp_path, value: str) -> None:
    from planodom.config import PlanodomConfig
    from planodom.errors import ConfigError

    (tmp_path / "c.yaml").write_text(f"odometry: {{map_lead_acceleration: {value}}}\n")
    field = r"c\.yaml: field 'odometry\.map_lead_acceleration'"
    with pytest.raises(ConfigError, match=field) as err:
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert "\n" not in str(err.value)
