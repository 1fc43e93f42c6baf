"""The typed rig: rig.yaml mappings validated once, round trips, and what a simulated rig states."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.errors import DatasetError, GeometryError
from planodom.rig import MotionBounds, Rig
from planodom.simulation import isoclinal_rig, lidar_rig


def test_round_trip_keeps_every_field_and_the_unknown_keys() -> None:
    data = {
        "epoch_rate": 20,
        "sensor_origins": [[1.0, 0.5, 0.8], [-1.0, -0.5, 0.8]],
        "motion_bounds": {"max_translation_m": 3.0},
        "extrinsics": [np.eye(4).tolist()],
        "notes": {"vehicle": "van"},
    }
    rig = Rig.from_dict(data)
    assert rig.epoch_rate_hz == 20.0 and isinstance(rig.epoch_rate_hz, float)
    assert rig.sensor_origins is not None and rig.sensor_origins.shape == (2, 3)
    assert rig.motion_bounds == MotionBounds(max_translation_m=3.0)
    assert rig.extra == {"notes": {"vehicle": "van"}}
    assert Rig.from_dict(rig.to_dict()).to_dict() == rig.to_dict() == data | {"epoch_rate": 20.0}
    assert Rig.from_dict(None).to_dict() == Rig().to_dict() == {}


def test_one_origin_for_all_rings_is_one_row() -> None:
    rig = Rig(sensor_origins=np.array([0.0, 0.0, 1.8]))  # built in code, not from YAML
    assert rig.sensor_origins is not None and rig.sensor_origins.shape == (1, 3)
    assert Rig.from_dict({"sensor_origins": [0.0, 0.0, 1.8]}).sensor_origins.shape == (1, 3)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"epoch_rate": 0}, "field 'epoch_rate' must be positive"),
        ({"epoch_rate": True}, "field 'epoch_rate' must be a positive number"),
        ({"sensor_origins": [[0, 0, float("nan")]]}, "field 'sensor_origins' must be finite"),
        ({"motion_bounds": [3.0]}, "field 'motion_bounds' must be a mapping"),
        ({"motion_bounds": {"max_rotation_deg": -1}}, "motion_bounds.max_rotation_deg"),
        ({"extrinsics": [(2 * np.eye(4)).tolist()]}, "last row of each must be 0 0 0 1"),
        ({"extrinsics": [[1, 2, 3]]}, "field 'extrinsics' must have shape Nx4x4"),
        # true / false were read as 1 / 0
        ({"sensor_origins": [[True, 0, 0]]}, "field 'sensor_origins' must be numbers, not"),
        ({"extrinsics": [np.eye(4).tolist()[:3] + [[0, 0, 0, True]]]}, "'extrinsics' must be"),
        # no rotation: accepted as a sensor's pose before
        ({"extrinsics": [np.diag([2.0, 2, 2, 1]).tolist()]}, "'extrinsics.0': not a rigid"),
        ({"extrinsics": [np.diag([1.0, 1, -1, 1]).tolist()]}, "'extrinsics.0'.*reflection"),
        ({"platform": "car"}, "field 'platform' must be vehicle or handheld .* got 'car'"),
        ({"platform": "Vehicle"}, "field 'platform' must be vehicle or handheld"),
        ({"platform": True}, "field 'platform' must be vehicle or handheld .* got True"),
        ({"platform": ["vehicle"]}, "field 'platform' must be vehicle or handheld"),
    ],
)
def test_bad_fields_fail_in_one_line_naming_source_and_field(data, message) -> None:
    with pytest.raises(DatasetError, match=message) as err:
        Rig.from_dict(data, source="my/rig.yaml")
    assert str(err.value).startswith("my/rig.yaml: ") and "\n" not in str(err.value)


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        (
            {"sensor_origins": np.zeros((3, 2))},
            r"sensor_origins must have shape \(S, 3\) or \(3,\)",
        ),
        ({"sensor_origins": np.zeros((2, 2))}, r"sensor_origins must have shape .* got \(2, 2\)"),
        ({"sensor_origins": [[0, 0, np.inf]]}, "sensor_origins must be finite"),
        ({"sensor_origins": "front"}, "sensor_origins must be numbers, got str"),
        ({"extrinsics": (np.eye(3),)}, r"extrinsics must be \(4, 4\) each, got \(3, 3\)"),
    ],
)
def test_a_rig_built_in_code_refuses_what_it_cannot_hold(fields, message) -> None:
    """A (3, 2) array of origins was reshaped to (2, 3), two made-up sensor positions; a
    (2, 2) one ended in numpy's reshape ValueError."""
    with pytest.raises(GeometryError, match=rf"^Rig: {message}"):
        Rig(**fields)
    assert Rig(sensor_origins=np.zeros((0, 3))).sensor_origins.shape == (0, 3)


@pytest.mark.parametrize("sensors", [isoclinal_rig(), lidar_rig(16)])
def test_a_simulated_rig_states_origins_per_ring_and_extrinsics_per_sensor(sensors) -> None:
    rig = sensors.dataset_rig(10.0)
    assert rig.epoch_rate_hz == 10.0 and len(rig.extrinsics) == len(sensors)
    assert rig.sensor_origins is not None and len(rig.sensor_origins) == sensors.n_rings
    for offset, sensor, T in zip(
        sensors.ring_offsets, sensors.sensors, rig.extrinsics, strict=True
    ):
        np.testing.assert_array_equal(T, sensor.T_base_sensor)
        rings = rig.sensor_origins[offset : offset + sensor.n_rings]
        np.testing.assert_array_equal(rings, np.broadcast_to(T[:3, 3], rings.shape))


@pytest.mark.parametrize("platform", ["vehicle", "handheld"])
def test_the_platform_round_trips_and_its_absence_is_unknown(platform: str) -> None:
    rig = Rig.from_dict({"epoch_rate": 10, "platform": platform})
    assert rig.platform == platform and rig.extra == {}
    assert rig.to_dict() == {"epoch_rate": 10.0, "platform": platform}
    assert Rig.from_dict(rig.to_dict()).platform == platform
    assert Rig.from_dict({"epoch_rate": 10}).platform is None  # an old rig.yaml
    assert "platform" not in Rig().to_dict()
    with pytest.raises(DatasetError, match="^Rig: platform must be vehicle or handheld"):
        Rig(platform="car")
