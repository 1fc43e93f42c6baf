"""The guard of refinement: moments (planodom.config.moment_refine)."""

import pytest

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError


def test_the_gate_is_off_by_default_and_read_from_a_file(tmp_path) -> None:
    assert PlanodomConfig().odometry.moment_gate_chi2 is None
    (tmp_path / "c.yaml").write_text("odometry: {refinement: moments, moment_gate_chi2: 20.5}\n")
    assert PlanodomConfig.from_yaml(tmp_path / "c.yaml").odometry.moment_gate_chi2 == 20.5


@pytest.mark.parametrize("value", ["-1", "0", "high"])
def test_a_bad_gate_names_file_and_field(tmp_path, value: str) -> None:
    (tmp_path / "c.yaml").write_text(f"odometry: {{moment_gate_chi2: {value}}}\n")
    with pytest.raises(ConfigError, match=r"c\.yaml: field 'odometry\.moment_gate_chi2'") as err:
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert "\n" not in str(err.value)


def test_the_translations_source_is_the_moments_by_default_and_read_from_a_file(tmp_path) -> None:
    assert PlanodomConfig().odometry.moment_translation == "moments"
    (tmp_path / "c.yaml").write_text("odometry: {moment_translation: offsets}\n")
    assert PlanodomConfig.from_yaml(tmp_path / "c.yaml").odometry.moment_translation == "offsets"
    (tmp_path / "c.yaml").write_text("odometry: {moment_translation: centroids}\n")
    with pytest.raises(ConfigError, match=r"c\.yaml: field 'odometry\.moment_translation'") as err:
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert "\n" not in str(err.value)


def test_the_guard_and_the_extractions_are_off_by_default_and_read_from_a_file(tmp_path) -> None:
    odo = PlanodomConfig().odometry
    assert odo.moment_after_ok == 0 and odo.moment_extractions == "all"
    (tmp_path / "c.yaml").write_text(
        "odometry: {moment_after_ok: 3, moment_extractions: committed}\n"
    )
    odo = PlanodomConfig.from_yaml(tmp_path / "c.yaml").odometry
    assert odo.moment_after_ok == 3 and odo.moment_extractions == "committed"
