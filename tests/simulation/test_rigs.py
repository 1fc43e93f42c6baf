"""Sensors and rigs: beam geometry and timing, the isoclinal default, rig.yaml round trip."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from planodom.errors import ConfigError, DatasetError
from planodom.simulation import (
    Scanner2D,
    SensorRig,
    SpinningLidar,
    isoclinal_normals,
    isoclinal_rig,
    lidar_rig,
    load_sensor_rig,
    rig_from_name,
    save_sensor_rig,
)


def test_scanner2d_beams_like_lms221():
    s = Scanner2D()
    assert s.directions.shape == (361, 1, 3)
    np.testing.assert_allclose(np.rad2deg(s.beam_angles[[0, -1]]), [-90, 90])
    np.testing.assert_allclose(np.linalg.norm(s.directions, axis=2), 1.0)
    np.testing.assert_array_equal(s.directions[..., 2], 0.0)  # in the x-y (scan) plane
    # the mirror turns 360 deg per period: a 180 deg sweep takes half of 1/75 s
    assert s.firing_times[-1] == pytest.approx(0.5 / 75.0)
    assert np.all(np.diff(s.firing_times) > 0)
    assert Scanner2D(step_deg=1.0).directions.shape == (181, 1, 3)


def test_spinning_lidar_beams():
    s = SpinningLidar(n_beams=32, vfov_deg=(-25, 15), n_columns=1024, rate_hz=10)
    assert s.directions.shape == (1024, 32, 3) and s.n_rings == 32
    np.testing.assert_allclose(np.linalg.norm(s.directions, axis=2), 1.0)
    el = np.rad2deg(np.arcsin(s.directions[..., 2]))
    np.testing.assert_allclose([el.min(), el.max()], [-25, 15])
    assert s.firing_times[-1] == pytest.approx(0.1 * 1023 / 1024)
    az = np.arctan2(s.directions[:, 0, 1], s.directions[:, 0, 0])
    assert np.all(np.diff(np.unwrap(az)) > 0)  # counter-clockwise


def test_isoclinal_default_geometry():
    rig = isoclinal_rig()
    assert len(rig) == 4 and rig.n_rings == 4
    np.testing.assert_array_equal(rig.ring_offsets, [0, 1, 2, 3])
    m = np.array([s.scan_plane_normal for s in rig.sensors])
    # isoclinal: all scan planes have the same inclination to the horizontal
    np.testing.assert_allclose(np.abs(m[:, 2]), np.cos(np.deg2rad(25.0)), atol=1e-12)
    for (i, j), meet in (((0, 1), 45.0), ((2, 3), -45.0)):
        h = np.cross(m[i], m[j])
        h /= np.linalg.norm(h)
        assert abs(h[2]) < 1e-12  # the pair meets along a horizontal direction ...
        expected = [np.cos(np.deg2rad(meet)), np.sin(np.deg2rad(meet)), 0.0]
        assert abs(h @ expected) == pytest.approx(1.0)  # ... yawed by +-45 deg
    # the forward pair looks forward, the backward pair backward
    look = np.array([s.T_base_sensor[:3, 0] for s in rig.sensors])
    assert np.all(look[:2, 0] > 0.7) and np.all(look[2:, 0] < -0.7)


def _best_crossing(rig: SensorRig, azimuth_deg: np.ndarray) -> np.ndarray:
    """Per wall normal azimuth, the best |n . h| / |h| over the rig's two pairs."""
    m = np.array([s.scan_plane_normal for s in rig.sensors])
    h = np.array([np.cross(m[0], m[1]), np.cross(m[2], m[3])])
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    a = np.deg2rad(azimuth_deg)
    n = np.column_stack([np.cos(a), np.sin(a), np.zeros_like(a)])
    return np.abs(n @ h.T).max(axis=1)


def test_default_pairs_cover_every_wall_orientation():
    az = np.arange(0.0, 180.0, 1.0)
    assert _best_crossing(isoclinal_rig(), az).min() >= np.cos(np.deg2rad(45.0)) - 1e-12
    # both pairs meeting along the forward axis leave side walls (normal along y) blind
    bad = isoclinal_rig(meet_deg=(0.0, 0.0))
    assert _best_crossing(bad, az).min() < 1e-12


@pytest.mark.parametrize("rig", [isoclinal_rig(noise_sigma=0.006), lidar_rig(64)])
def test_rig_yaml_round_trip(tmp_path, rig):
    path = tmp_path / "rig.yaml"
    save_sensor_rig(rig, path)
    back = load_sensor_rig(path)
    assert back.to_dict() == rig.to_dict()
    for a, b in zip(rig.sensors, back.sensors, strict=True):
        assert type(a) is type(b)
        np.testing.assert_array_equal(a.T_base_sensor, b.T_base_sensor)
        np.testing.assert_array_equal(a.directions, b.directions)
        np.testing.assert_array_equal(a.firing_times, b.firing_times)
    assert (
        yaml.safe_load(path.read_text())["sensors"][0]["noise_sigma"] == rig.sensors[0].noise_sigma
    )


def _scaled(sensor: dict, factor: float) -> list:
    T = np.array(sensor["T_base_sensor"])
    T[:3, :3] *= factor
    return T.tolist()


def test_a_rotation_written_with_four_decimals_is_a_rotation(tmp_path):
    """A hand-written rig file's 0.7071 (off by ~1e-4) was refused by a 1e-6 bound that no
    other reader of rotations used; the shared bound (planodom.geometry.ROTATION_TOL) takes
    it, as it takes a KITTI pose written with as many digits."""
    data = isoclinal_rig().to_dict()
    c = round(float(np.cos(np.pi / 4)), 4)
    data["sensors"][0]["T_base_sensor"] = [
        [c, -c, 0.0, 1.0],
        [c, c, 0.0, 0.5],
        [0.0, 0.0, 1.0, 0.8],
        [0.0, 0.0, 0.0, 1.0],
    ]
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(data))
    assert load_sensor_rig(path).sensors[0].T_base_sensor[0, 0] == c


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: d["sensors"][1].update(type="radar"), "sensors.1.type"),
        (lambda d: d["sensors"][0].update(rate_hz=-1.0), "sensors.0.*rate_hz"),
        (lambda d: d["sensors"][0].update(colour="red"), "sensors.0.*colour"),
        (lambda d: d["sensors"][2].update(T_base_sensor=np.eye(3).tolist()), "sensors.2.*4x4"),
        (lambda d: d["sensors"][3].update(T_base_sensor=(2 * np.eye(4)).tolist()), "sensors.3"),
        (lambda d: d.pop("sensors"), "sensors"),
        # true / false were read as 1 / 0
        (lambda d: d["sensors"][0].update(max_range=True), "sensors.0.max_range.*boolean"),
        (lambda d: d["sensors"][1].update(noise_sigma=False), "sensors.1.noise_sigma.*boolean"),
        # a string: Python's "'>' not supported between ..." before; no sensors: no file named
        (lambda d: d["sensors"][0].update(rate_hz="fast"), "sensors.0.rate_hz': expected numbers"),
        (lambda d: d.update(sensors=[]), "'sensors': the list is empty"),
        # a scaled rotation block (the shared check of planodom.geometry)
        (
            lambda d: d["sensors"][0].update(T_base_sensor=_scaled(d["sensors"][0], 1.01)),
            "sensors.0.*not a rigid transform.*column norms",
        ),
    ],
)
def test_bad_rig_files_name_file_and_field(tmp_path, mutate, message):
    data = isoclinal_rig().to_dict()
    mutate(data)
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(DatasetError, match=f"rig.yaml.*{message}"):
        load_sensor_rig(path)
    with pytest.raises(ConfigError):
        SensorRig.from_dict(data)


def test_named_rigs():
    assert rig_from_name("lidar32").sensors[0].n_beams == 32
    assert rig_from_name("lidar16").n_rings == 16
    with pytest.raises(ConfigError, match="unknown rig"):
        rig_from_name("kinect")
    with pytest.raises(DatasetError, match="nope.yaml"):
        load_sensor_rig("/nonexistent/nope.yaml")


@given(st.floats(-180, 180), st.floats(5, 60), st.floats(-180, 180))
def test_isoclinal_trace_crossing_angle(meet_deg, inclination_deg, wall_azimuth_deg):
    """Traces m x n of a rolled pair on a vertical wall cross at 2 atan(tan(theta) |n.h|)."""
    m = isoclinal_normals(meet_deg, inclination_deg)
    np.testing.assert_allclose(np.arccos(m[:, 2]), np.deg2rad(inclination_deg), atol=1e-9)
    a = np.deg2rad(wall_azimuth_deg)
    n = np.array([np.cos(a), np.sin(a), 0.0])
    t = np.cross(m, n)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    h = np.cross(m[0], m[1])
    h /= np.linalg.norm(h)
    expected = 2 * np.arctan(np.tan(np.deg2rad(inclination_deg)) * abs(n @ h))
    expected = min(expected, np.pi - expected)  # lines: the acute angle
    assert np.arccos(min(1.0, abs(t[0] @ t[1]))) == pytest.approx(expected, abs=1e-6)


def test_a_fractional_beam_count_is_refused(tmp_path):
    """n_beams: 2.5 loaded, then failed deep in the simulator with a TypeError."""
    data = lidar_rig().to_dict()
    data["sensors"][0]["n_beams"] = 2.5
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(
        DatasetError, match=r"rig\.yaml: field 'sensors\.0\.n_beams': expected a whole"
    ):
        load_sensor_rig(path)
