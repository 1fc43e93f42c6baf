"""The lead of a plane-map epoch's own twist to its sweep's middle
(:func:`planodom.odometry.trend.led_twist`, :func:`planodom.odometry.trend.map_lead`)."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import OdometryConfig
from planodom.geometry import invert_transform, se3_exp, se3_log
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.trend import led_twist, map_lead

#: a body twist changing linearly in time (rad/s and m/s, and per second): a roll rate
#: swinging up and a car braking in a tightening turn
TWIST0 = np.array([0.05, -0.02, 0.3, 8.0, 0.1, 0.05])
ACCEL = np.array([0.6, 0.2, 0.4, -2.0, 0.3, -0.1])


def _pose(t: float, n: int = 4000) -> np.ndarray:
    """T_world_base at ``t`` s under the body twist TWIST0 + ACCEL t from the identity at 0:
    the product of many short steps (an independent integration, not a closed form)."""
    T = np.eye(4)
    h = t / n
    for i in range(n):
        T = T @ se3_exp((TWIST0 + ACCEL * (i + 0.5) * h) * h)
    return T


def _step_twist(a: float, b: float) -> np.ndarray:
    """The twist of the step from ``a`` to ``b`` s (what an epoch's own twist measures)."""
    return se3_log(invert_transform(_pose(a)) @ _pose(b)) / (b - a)


def test_the_lead_of_two_steps_gives_the_twist_at_the_epoch():
    """Under a twist linear in time, the constant twist of a step is the twist at its
    middle, and led along the change from the step before (of another length) it is the
    constant twist of a sweep centred on the step's end (what the epoch is deskewed
    with), where the step's own lags by half a step."""
    t0, t1, t2 = 0.40, 0.50, 0.61  # sweep middles: steps of 0.10 and 0.11 s
    previous, own = _step_twist(t0, t1), _step_twist(t1, t2)
    sweep = _step_twist(t2 - 0.05, t2 + 0.05)
    got = led_twist(own, True, t2 - t1, previous, t1 - t0)
    lag = np.abs(own - sweep)
    np.testing.assert_allclose(lag, np.abs(ACCEL) * (t2 - t1) / 2, rtol=0.2, atol=2e-3)
    # left: the steps' and the sweep's different lengths (third order in the step)
    assert np.all(np.abs(got - sweep) < 0.1 * lag + 1e-4), (got - sweep, lag)


def test_unknown_or_unmeasured_parts_are_not_led():
    own = np.array([0.1, 0.0, 0.2, 5.0, 0.0, 0.0])
    previous = np.array([0.0, 0.0, 0.1, np.nan, np.nan, np.nan])
    got = led_twist(own, True, 0.1, previous, 0.1)
    np.testing.assert_allclose(got, [0.15, 0.0, 0.25, 5.0, 0.0, 0.0])
    full = np.array([0.0, 0.0, 0.1, 4.0, 0.0, 0.0])
    np.testing.assert_allclose(led_twist(own, False, 0.1, full, 0.1)[3:], own[3:])
    np.testing.assert_allclose(led_twist(own, True, 0.1, full, 0.1)[3:], [5.5, 0.0, 0.0])
    np.testing.assert_array_equal(led_twist(own, True, 0.0, full, 0.1), own)


def _relative(status: Status) -> RelativePose:
    return RelativePose(np.eye(4), None, status)


@pytest.mark.parametrize("mode", ["rate", "twist"])
def test_map_lead_takes_the_previous_epochs_own_twist(mode: str):
    config = OdometryConfig(map_twist_lead=mode, map_lead_iterations=4)
    twist = np.arange(6.0)
    recent = [(3, twist + 1), (4, twist)]
    times = [0.0, 0.1, 0.25]
    got = map_lead(recent, 5, times, _relative(Status.OK), config)
    assert got is not None and got.previous is not None
    np.testing.assert_allclose(got.previous[:3], twist[:3])
    assert got.previous_dt == pytest.approx(0.15)
    assert got.iterations == 4
    assert got.rate_tolerance_deg_s == config.map_lead_rate_tolerance_deg_s
    if mode == "rate":
        assert np.all(np.isnan(got.previous[3:]))
    else:
        np.testing.assert_allclose(got.previous[3:], twist[3:])
    degenerate = map_lead(recent, 5, times, _relative(Status.DEGENERATE), config)
    assert degenerate is not None and degenerate.previous is not None
    assert np.all(np.isnan(degenerate.previous[3:]))
    # the previous epoch did not measure its rate: nothing led, the tolerances still hold
    for lost in (map_lead(recent, 6, times, _relative(Status.OK), config),
                 map_lead([], 5, times, _relative(Status.OK), config)):  # fmt: skip
        assert lost is not None and lost.previous is None
        own = np.ones(6)
        np.testing.assert_array_equal(lost.led(own, True, 0.1), own)
    off = OdometryConfig(map_twist_lead="off")
    assert map_lead(recent, 5, times, _relative(Status.OK), off) is None


def test_the_lead_refines_with_its_own_tolerances():
    """An own twist 0.3 deg/s and 0.1 m/s off the one used is within the general
    tolerances (0.5 each, unchanged) but beyond the lead's (0.1 deg/s, 0.05 m/s)."""
    from planodom.odometry.twist_refine import refined_twist

    used = np.zeros(6)
    own = np.r_[np.radians([0.3, 0.0, 0.0]), 0.1, 0.0, 0.0]
    config = OdometryConfig(map_twist_lead="rate")
    np.testing.assert_array_equal(refined_twist(own, used, True, config), used)
    lead = map_lead([], 1, [0.0], None, config)
    np.testing.assert_array_equal(refined_twist(own, used, True, config, lead), own)
    np.testing.assert_array_equal(refined_twist(own, used, False, config, lead)[3:], 0.0)


def test_the_shrunk_lead_keeps_a_change_beyond_its_noise_and_halves_one_at_it():
    from planodom.odometry.trend import shrunk_lead

    lead = np.array([0.5, -0.2, 0.1])
    change = np.array([1.0, 0.02, 0.1])
    variance = np.array([1e-6, 0.02**2, np.nan])
    got = shrunk_lead(lead, change, variance)
    assert got[0] == pytest.approx(lead[0], rel=1e-5)  # far beyond the noise: in full
    assert got[1] == pytest.approx(0.5 * lead[1])  # at one sigma: c^2 / (c^2 + c^2)
    assert got[2] == lead[2]  # the noise unknown: led as without shrinking
    np.testing.assert_array_equal(shrunk_lead(lead, np.zeros(3), np.ones(3)), lead)


@pytest.mark.parametrize("accel", [0.0, 2.0])
def test_the_shrunk_lead_is_nearer_the_true_rate_than_the_full_lead(accel: float):
    """Own rates of 0.1 s steps with noise of 0.01 rad/s, under a constant rate (its
    change is all noise: the full lead carries 1.6x it) and a rate changing at 2 rad/s^2
    (a change of 0.2 rad/s, twenty sigmas: led in full): the error against the true rate
    at the next sweep's middle (half a step on), over 4000 draws."""
    rng = np.random.default_rng(0)
    dt, sigma, n = 0.1, 0.01, 4000
    # the own rate of a step is the true rate at its middle; the sweep's half a step on
    previous = -0.5 * accel * dt + rng.normal(0, sigma, (n, 3))
    own = 0.5 * accel * dt + rng.normal(0, sigma, (n, 3))
    true = accel * dt
    config = OdometryConfig(map_twist_lead="rate", map_lead_shrink="stated")
    cov = np.diag(np.r_[np.full(3, (sigma * dt) ** 2), 1e-4, 1e-4])
    errors = {"full": [], "shrunk": []}
    for p, o in zip(previous, own, strict=True):
        twist_p, twist_o = np.r_[p, 1.0, 0, 0], np.r_[o, 1.0, 0, 0]
        lead = map_lead([(0, twist_p)], 1, [0.0, dt], _relative(Status.OK), config,
                        [np.full(3, sigma**2)])  # fmt: skip
        assert lead is not None
        step = RelativePose(np.eye(4), cov, Status.OK)
        errors["shrunk"].append(lead.led(twist_o, True, dt, step)[:3] - true)
        errors["full"].append(lead.led(twist_o, True, dt)[:3] - true)
    rms = {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in errors.items()}
    if accel == 0.0:
        assert rms["full"] == pytest.approx(np.sqrt(2.5) * sigma, rel=0.05)
        assert rms["shrunk"] < 0.9 * rms["full"]  # 0.87: the gain is itself noisy
    else:
        assert rms["full"] == pytest.approx(np.sqrt(2.5) * sigma, rel=0.05)  # unbiased
        assert rms["shrunk"] < 1.02 * rms["full"]


def test_map_lead_shrink_off_keeps_the_full_lead():
    config = OdometryConfig(map_twist_lead="rate", map_lead_shrink="off")
    lead = map_lead([(0, np.zeros(6))], 1, [0.0, 0.1], _relative(Status.OK), config,
                    [np.ones(3)])  # fmt: skip
    assert lead is not None and lead.previous_var is None


@pytest.mark.parametrize("value", ["on", "1", "fitted"])
def test_a_bad_map_lead_shrink_names_file_and_field(tmp_path, value: str) -> None:
    from planodom.config import PlanodomConfig
    from planodom.errors import ConfigError

    (tmp_path / "c.yaml").write_text(f"odometry: {{map_lead_shrink: {value}}}\n")
    with pytest.raises(ConfigError, match=r"c\.yaml: field 'odometry\.map_lead_shrink'") as err:
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert "\n" not in str(err.value)


def test_a_vertical_velocity_error_tilts_a_swept_floor_by_its_closed_form():
    """Why the lead's speed tolerance matters indoors (LIDAR13, docs/RESULTS.md): a spinning
    lidar's sweep of period T starts and ends behind the sensor, so a level floor seen in a
    ring of radius r while the sensor rises at v, deskewed with a vertical velocity off by
    d, is left with a height error d t that is a sawtooth in the azimuth (t = theta T /
    2 pi about the sweep's middle); its least-squares plane is tilted about the forward
    axis (a roll) by d T / (pi r), the continuous ring's closed form (int theta sin theta
    / int sin^2 theta = 2 over one turn). 3 cm/s at 10 Hz and 3 m: 0.018 deg, twice the
    indoor world 329's per-step roll error."""
    from planodom.extraction.deskew import deskew_points

    T, r, h, v, d = 0.1, 3.0, 1.8, 0.07, 0.03
    theta = np.linspace(-np.pi, np.pi, 20001)[:-1] + np.pi / 20000  # one turn, middle at 0
    t = theta * T / (2 * np.pi)  # seconds from the sweep's middle
    # the sensor at height v t over a level floor 1.8 m below it at t = 0
    seen = np.c_[r * np.cos(theta), r * np.sin(theta), -h - v * t]
    twist = np.array([0.0, 0.0, 0.0, 0.0, 0.0, v + d])
    p = deskew_points(seen, t, twist)
    # least-squares plane z = a x + b y + c through the deskewed floor
    (a, b, c), *_ = np.linalg.lstsq(np.c_[p[:, 0], p[:, 1], np.ones(len(p))], p[:, 2], rcond=None)
    assert abs(a) < 1e-9 and c == pytest.approx(-h, abs=1e-6)
    assert np.degrees(np.arctan(b)) == pytest.approx(np.degrees(d * T / (np.pi * r)), rel=1e-3)
    assert np.degrees(d * T / (np.pi * r)) == pytest.approx(0.018, abs=5e-4)
    # deskewed with the true velocity the floor is level
    level = deskew_points(seen, t, np.r_[0.0, 0.0, 0.0, 0.0, 0.0, v])
    np.testing.assert_allclose(level[:, 2], -h, atol=1e-12)


@pytest.mark.parametrize("radius", [3.0, 10.0, 30.0])
def test_a_pitch_rate_error_tilts_a_swept_ground_in_roll_at_any_range(radius: float):
    """Why the lead's rate tolerance reaches the roll (LIDAR15, docs/RESULTS.md): a level
    ground seen in a ring of radius r by a spinning lidar whose sweep of period T starts and
    ends behind the sensor, while the vehicle pitches at w, deskewed with a pitch rate off
    by e, has its points turned about y by e t (t = theta T / 2 pi about the sweep's
    middle), a height error -e t r cos(theta); its least-squares plane is tilted about the
    forward axis (a roll) by e T / (4 pi), the continuous ring's closed form (int theta
    sin(2 theta) / 2 over one turn is -pi / 2, over int r^2 sin^2 = pi r^2), whatever the
    radius. 0.1 deg/s at 10 Hz: 0.0008 deg; the vertical velocity's tilt, d T / (pi r),
    falls with the range, this one does not. The sensor's pitch is made with scipy, not
    with the code's deskewing."""
    from scipy.spatial.transform import Rotation

    from planodom.extraction.deskew import deskew_points

    T, h, w, e = 0.1, 1.8, np.radians(2.0), np.radians(0.1)
    theta = np.linspace(-np.pi, np.pi, 20001)[:-1] + np.pi / 20000  # one turn, middle at 0
    t = theta * T / (2 * np.pi)  # seconds from the sweep's middle
    ground = np.c_[radius * np.cos(theta), radius * np.sin(theta), np.full_like(theta, -h)]
    # each point seen in the base frame of its own time, the base pitched by w t
    seen = Rotation.from_rotvec(np.outer(w * t, [0.0, 1.0, 0.0])).inv().apply(ground)

    def plane(p: np.ndarray) -> np.ndarray:
        """(a, b, c) of the least-squares z = a x + b y + c."""
        a = np.c_[p[:, 0], p[:, 1], np.ones(len(p))]
        return np.linalg.lstsq(a, p[:, 2], rcond=None)[0]

    level = plane(deskew_points(seen, t, np.r_[0.0, w, 0.0, 0.0, 0.0, 0.0]))
    np.testing.assert_allclose(level, [0.0, 0.0, -h], atol=1e-9)
    a, b, c = plane(deskew_points(seen, t, np.r_[0.0, w + e, 0.0, 0.0, 0.0, 0.0]))
    assert abs(a) < 1e-8 and c == pytest.approx(-h, abs=1e-6)
    assert np.arctan(b) == pytest.approx(e * T / (4 * np.pi), rel=1e-3)
    assert np.degrees(e * T / (4 * np.pi)) == pytest.approx(0.0008, abs=1e-5)


@pytest.mark.parametrize("vertical", [None, 0.01])
def test_the_vertical_tolerance_takes_the_vertical_velocity_alone(vertical):
    """An own velocity 3 cm/s off the one used along x and along z (world 329's rms error
    of the vertical velocity its epochs were finally deskewed with) is within the lead's
    speed tolerance (5 cm/s): nothing is taken by default; with ``odometry.
    map_lead_vertical_tolerance_mps`` 1 cm/s the vertical velocity is, the rest not."""
    from planodom.odometry.twist_refine import refined_twist

    used = np.zeros(6)
    own = np.r_[0.0, 0.0, 0.0, 0.03, 0.0, 0.03]
    config = OdometryConfig(map_twist_lead="rate", map_lead_vertical_tolerance_mps=vertical)
    lead = map_lead([], 1, [0.0], None, config)
    got = refined_twist(own, used, True, config, lead)
    np.testing.assert_array_equal(got, used if vertical is None else np.r_[0.0, 0, 0, 0, 0, 0.03])
    np.testing.assert_array_equal(refined_twist(own, used, False, config, lead), used)
    # beyond the speed tolerance the whole velocity is taken as before
    far = np.r_[0.0, 0.0, 0.0, 0.06, 0.0, 0.03]
    np.testing.assert_array_equal(refined_twist(far, used, True, config, lead), far)


@pytest.mark.parametrize("value", ["0", "-0.01", "off", ".nan"])
def test_a_bad_vertical_tolerance_names_file_and_field(tmp_path, value: str) -> None:
    from planodom.config import PlanodomConfig
    from planodom.errors import ConfigError

    (tmp_path / "c.yaml").write_text(f"odometry: {{map_lead_vertical_tolerance_mps: {value}}}\n")
    field = r"c\.yaml: field 'odometry\.map_lead_vertical_tolerance_mps'"
    with pytest.raises(ConfigError, match=field) as err:
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert "\n" not in str(err.value)
