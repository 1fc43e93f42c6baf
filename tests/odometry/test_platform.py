"""The platform a run assumes (planodom.odometry.platform, ``odometry.platform``): an explicit
option beats the platform, the config's platform beats the dataset's, and only a vehicle
switches ``start_vehicle_twist`` on."""

from __future__ import annotations

from pathlib import Path

import pytest

from planodom.config import PlanodomConfig
from planodom.odometry import run_odometry, with_platform
from planodom.odometry.platform import VEHICLE_OPTIONS, resolved_platform
from planodom.rig import Rig

# (config's odometry fields, the dataset's platform) -> (platform, start_vehicle_twist),
# written from the field's documented rule, not from running the code
CASES = [
    ({}, None, "unknown", False),
    ({}, "vehicle", "vehicle", True),
    ({}, "handheld", "handheld", False),
    ({"platform": "vehicle"}, None, "vehicle", True),
    ({"platform": "vehicle"}, "handheld", "vehicle", True),
    ({"platform": "handheld"}, "vehicle", "handheld", False),
    ({"platform": "unknown"}, "vehicle", "unknown", False),
    ({"start_vehicle_twist": False}, "vehicle", "vehicle", False),
    ({"platform": "vehicle", "start_vehicle_twist": False}, None, "vehicle", False),
    ({"start_vehicle_twist": True}, "handheld", "handheld", True),
    ({"start_vehicle_twist": True}, None, "unknown", True),
]


@pytest.mark.parametrize(("fields", "declared", "platform", "start"), CASES)
def test_explicit_beats_platform_beats_dataset(
    fields: dict, declared: str | None, platform: str, start: bool
) -> None:
    config = PlanodomConfig.from_dict({"odometry": fields})
    resolved = with_platform(config, Rig(platform=declared))
    assert resolved.odometry.platform == platform
    assert resolved.odometry.start_vehicle_twist is start
    # gap_tilt follows the platform as start_vehicle_twist does (never set in CASES)
    assert resolved.odometry.gap_tilt == ("held" if platform == "vehicle" else "widened")
    assert resolved_platform(config.odometry.platform, declared) == platform
    # resolving again, or the config.yaml a run writes of it on any dataset, changes nothing
    again = PlanodomConfig.from_dict(resolved.model_dump(mode="json"))
    for other in (None, "vehicle", "handheld"):
        assert with_platform(again, Rig(platform=other)).odometry == resolved.odometry
    assert with_platform(resolved, Rig(platform=declared)) is resolved


@pytest.mark.parametrize("value", [False, True])
def test_a_value_from_a_file_stays_explicit_through_derived_configs(
    tmp_path: Path, value: bool
) -> None:
    path = tmp_path / "c.yaml"
    path.write_text(f"odometry:\n  start_vehicle_twist: {str(value).lower()}\n")
    derived = (
        PlanodomConfig.from_yaml(path)
        .updated({"odometry.pipeline": "wocsc", "extraction.sweep": {"rotation": "ccw"}})
        .updated_fields({"association.max_translation_m": 4.0})
    )
    assert with_platform(derived, Rig(platform="vehicle")).odometry.start_vehicle_twist is value


def test_an_unset_option_stays_unset_through_derived_configs() -> None:
    # the experiments' overrides, the smoothing's and a rig's motion bounds all go through
    # updated(): the option must still follow the platform after them
    derived = PlanodomConfig().updated({"odometry.delta": 1, "association.max_rotation_deg": 50})
    assert "start_vehicle_twist" not in derived.odometry.model_fields_set
    assert with_platform(derived, Rig(platform="vehicle")).odometry.start_vehicle_twist
    assert not with_platform(derived, Rig()).odometry.start_vehicle_twist


def test_every_vehicle_option_is_an_odometry_field_off_by_default() -> None:
    defaults = PlanodomConfig().odometry
    for name, value in VEHICLE_OPTIONS.items():
        assert getattr(defaults, name) != value


def test_run_odometry_runs_with_the_datasets_platform() -> None:
    class Source(list):  # two epochs of no planes, with a rig as a dataset has
        rig = Rig(platform="vehicle")

    run = run_odometry(Source([[], []]), times=[0.0, 0.1])
    assert run.config is not None
    assert (run.config.odometry.platform, run.config.odometry.start_vehicle_twist) == (
        "vehicle",
        True,
    )
    config = PlanodomConfig().updated({"odometry.platform": "handheld"})
    run = run_odometry(Source([[], []]), config, times=[0.0, 0.1])
    assert run.config is not None and not run.config.odometry.start_vehicle_twist
    run = run_odometry([[], []], times=[0.0, 0.1])  # no rig: unknown
    assert run.config is not None and run.config.odometry.platform == "unknown"
