"""Per-point times from the azimuth under a declared sweep convention (extraction.sweep)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planodom.config import ExtractionConfig, PlanodomConfig
from planodom.config.extraction import SweepConfig
from planodom.errors import ConfigError
from planodom.extraction import extract
from planodom.extraction.lidar.sweep import (
    SEAM_TOLERANCE,
    AzimuthTimedScan,
    rig_lidar_pose,
    sweep_timed,
    sweep_times,
    with_sweep_times,
)
from planodom.geometry import make_transform
from planodom.rig import Rig
from planodom.scan import Scan
from planodom.simulation.sensors import SpinningLidar

from .synth_scans import default_scene, planes_in_base, scan_lidar


def _lidar_points(lidar: SpinningLidar, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Every ray of one sweep at a random range, in the base frame, and its firing time
    (the simulator's sensor model: the truth the recovered times are compared with)."""
    d = lidar.directions  # (F, G, 3) sensor frame
    ranges = rng.uniform(1.0, 60.0, d.shape[:2])
    p_sensor = (d * ranges[..., None]).reshape(-1, 3)
    T = lidar.T_base_sensor
    p_base = p_sensor @ T[:3, :3].T + T[:3, 3]
    t = np.repeat(lidar.firing_times, d.shape[1])
    return p_base, t


@pytest.mark.parametrize("yaw_deg", [0.0, 37.0, -120.0])
def test_times_of_a_simulated_lidar_mounted_off_the_base_origin(yaw_deg):
    # A lidar turned about z and mounted off the origin, tilted slightly: the azimuths are
    # taken in its own frame, so every column's firing time comes back exactly.
    R = Rotation.from_euler("zyx", [yaw_deg, 2.0, -1.5], degrees=True).as_matrix()
    lidar = SpinningLidar(make_transform(R, [0.7, -0.3, 1.6]), n_beams=8, n_columns=360,
                          rate_hz=20.0)  # fmt: skip
    p, t_true = _lidar_points(lidar, np.random.default_rng(1))
    sweep = SweepConfig(rotation="ccw", start_azimuth_deg=-180.0, period_s=0.05)
    t = sweep_times(p, sweep, lidar.T_base_sensor)
    np.testing.assert_allclose(t, t_true, atol=1e-12)
    # in the base frame (the extrinsic ignored) the times are wrong by the yaw
    if yaw_deg:
        assert np.abs(sweep_times(p, sweep) - t_true).max() > 1e-3


def test_clockwise_sweep_stamped_facing_forward():
    # KITTI's convention: clockwise, the seam behind, the epoch stamped when the sensor
    # faces forward (half a turn after the start of a 0.1 s sweep).
    sweep = SweepConfig(rotation="cw", start_azimuth_deg=180.0, period_s=0.1, start_time_s=-0.05)
    p = np.array([[10.0, 0, 0], [0, -5.0, 1.0], [0, 5.0, 0], [-3.0, -1e-9, 0], [1, 1, 0]])
    # forward: 0; right (azimuth -90 deg, a quarter turn after forward): +0.025 s; left:
    # -0.025 s; just right of behind: the start of the sweep; 45 deg left: -0.0125 s
    np.testing.assert_allclose(sweep_times(p, sweep), [0.0, 0.025, -0.025, -0.05, -0.0125],
                               atol=1e-9)  # fmt: skip


def test_seam_round_off_is_not_a_whole_period_late():
    # a first-column point whose azimuth rounds to just below the start (one turn minus
    # round-off) belongs to the start of the sweep
    sweep = SweepConfig(rotation="ccw", start_azimuth_deg=0.0, period_s=0.1)
    p = np.array([[5.0, -1e-15, 0.0], [5.0, -5e-3, 0.0]])  # the second: 0.06 deg before
    t = sweep_times(p, sweep)
    assert t[0] == 0.0
    assert t[1] == pytest.approx(0.1 * (1 - np.arctan2(5e-3, 5.0) / (2 * np.pi)), abs=1e-12)


def _numpy_times(points, sweep):
    """The times written with numpy's floor modulo, as sweep_times computed them before
    its compiled pass (points in the sensor frame)."""
    azimuth = np.arctan2(points[:, 1], points[:, 0])
    sense = 1.0 if sweep.rotation == "ccw" else -1.0
    turn = sense * (azimuth - np.radians(sweep.start_azimuth_deg)) / (2.0 * np.pi)
    frac = np.mod(turn, 1.0)
    frac[frac > 1.0 - SEAM_TOLERANCE] = 0.0
    return sweep.start_time_s + sweep.period_s * frac


@pytest.mark.parametrize(
    ("rotation", "start_deg", "period", "t0"),
    [("ccw", -180.0, 0.05, 0.0), ("cw", 180.0, 0.1, -0.05), ("ccw", 0.0, 0.1, 0.0),
     ("cw", 37.5, 0.1, 0.01)],
)  # fmt: skip
def test_times_equal_numpys_floor_modulo_bit_for_bit(rotation, start_deg, period, t0):
    """Random azimuths, azimuths on the start and one ulp around it, the seam (signed
    zeros, -pi and pi), the origin and a NaN: the same float64 as numpy's expression."""
    sweep = SweepConfig(
        rotation=rotation, start_azimuth_deg=start_deg, period_s=period, start_time_s=t0
    )
    rng = np.random.default_rng(21)
    a0 = np.radians(start_deg)
    ang = np.concatenate([rng.uniform(-np.pi, np.pi, 4000), [a0, np.nextafter(a0, 9.0),
                          np.nextafter(a0, -9.0), np.pi, -np.pi]])  # fmt: skip
    p = np.column_stack([np.cos(ang), np.sin(ang), rng.normal(size=len(ang))])
    seam = [[-1.0, 0.0, 0], [-1.0, -0.0, 0], [-1.0, -1e-300, 0], [0.0, 0.0, 0], [0.0, -0.0, 0]]
    p = np.vstack([p * rng.uniform(0.5, 80.0, (len(p), 1)), seam, [[np.nan, 1.0, 0.0]]])
    got, want = sweep_times(p, sweep), _numpy_times(p, sweep)
    assert np.array_equal(got, want, equal_nan=True)
    assert np.array_equal(np.signbit(got), np.signbit(want))


def test_no_convention_declared_keeps_scans_as_they_are():
    scan = Scan(np.random.default_rng(0).normal(size=(20, 3)))
    assert with_sweep_times(scan, SweepConfig()) is scan
    source = [scan]
    assert sweep_timed(source, SweepConfig(), None) is source
    with pytest.raises(ConfigError, match="declares no convention"):
        sweep_times(scan.points, SweepConfig())
    # times a scan carries are kept
    timed = Scan(scan.points, t=np.linspace(0.0, 0.1, 20))
    declared = SweepConfig(rotation="cw")
    assert with_sweep_times(timed, declared) is timed
    wrapped = sweep_timed([timed, scan, []], declared, Rig())
    assert wrapped[0] is timed and wrapped[2] == [] and len(wrapped) == 3
    assert wrapped[1].t is not None and np.all((wrapped[1].t >= 0) & (wrapped[1].t < 0.1))


def test_config_is_validated():
    cfg = PlanodomConfig().updated({"extraction.sweep": {"rotation": "cw", "period_s": 0.05}})
    assert cfg.extraction.sweep.rotation == "cw" and cfg.extraction.sweep.period_s == 0.05
    assert PlanodomConfig().extraction.sweep.rotation == "none"  # off by default
    for bad, field in (
        ({"rotation": "clockwise"}, "rotation"),
        ({"period_s": 0.0}, "period_s"),
        ({"start_azimuth_deg": 400.0}, "start_azimuth_deg"),
        ({"period_s": 0.1, "start_time_s": -0.2}, "start_time_s"),
    ):
        with pytest.raises(ConfigError, match=f"extraction.sweep.{field}"):
            PlanodomConfig().updated({"extraction.sweep": bad})


def test_rig_lidar_pose():
    T = make_transform(np.eye(3), [0.0, 0.0, 1.2])
    assert rig_lidar_pose(None) is None and rig_lidar_pose(Rig()) is None
    np.testing.assert_array_equal(rig_lidar_pose(Rig(extrinsics=(T, T.copy()))), T)
    with pytest.raises(ConfigError, match="different extrinsics"):
        rig_lidar_pose(Rig(extrinsics=(T, np.eye(4))))


def _plane_errors(planes, truth) -> list[tuple[int, float, float]]:
    """(truth id, normal error deg, offset error m) of each plane against ``truth``."""
    out = []
    for p in planes:
        n, d = truth[p.truth_id]
        angle = float(np.degrees(np.arccos(np.clip(p.normal @ n, -1.0, 1.0))))
        out.append((p.truth_id, angle, abs(p.offset - d)))
    return out


def test_recovered_times_deskew_an_unorganised_cloud_without_changing_its_segmentation():
    # A 32-beam lidar turning at 0.6 rad/s and driving at 8 m/s, stored without ring and
    # times (ccw, first column at azimuth 0, 0.1 s: the synthetic sensor's convention).
    scene = default_scene()
    truth = planes_in_base(scene)
    twist = np.array([0.0, 0.0, 0.6, 8.0, 0.5, 0.0])
    scan = scan_lidar(scene, twist=twist, with_ring=False)
    bare = Scan(scan.points, None, None, scan.label)
    sweep = SweepConfig(rotation="ccw", start_azimuth_deg=0.0, period_s=0.1)
    timed = with_sweep_times(bare, sweep)
    assert isinstance(timed, AzimuthTimedScan)
    # the marker survives dataclasses.replace (the odometry's deskew passes use it)
    assert isinstance(replace(timed, t=np.zeros_like(timed.t)), AzimuthTimedScan)
    np.testing.assert_allclose(timed.t, scan.t, atol=1e-12)  # the firing times
    origin = np.array([0.0, 0.0, 1.8])
    cfg = ExtractionConfig()
    untimed = extract(bare, cfg, sensor_origins=origin)
    # Without a twist the recovered times change nothing: the same organised segmentation
    # (recorded times would take the recovered rows as rings instead).
    same = extract(timed, cfg, sensor_origins=origin)
    assert len(same.planes) == len(untimed.planes)
    for a, b in zip(untimed.planes, same.planes, strict=True):
        np.testing.assert_array_equal(a.coefficients, b.coefficients)
    # The smear is large without deskewing: some wall is off by a degree or more.
    assert max(e for _, e, _ in _plane_errors(untimed.planes, truth)) > 1.0
    # Deskewed with the true twist: one plane per true wall, each exact.
    deskewed = extract(timed, cfg, twist=twist, sensor_origins=origin)
    errors = _plane_errors(deskewed.planes, truth)
    assert sorted(k for k, _, _ in errors) == sorted(truth)
    for _, angle, offset in errors:
        assert angle < 0.01 and offset < 1e-3
