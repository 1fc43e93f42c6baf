"""The candidate rotation of an LDA pair (planodom.config.pair_rotation)."""

import pytest

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError


@pytest.mark.parametrize("value", ["weighted", "winner"])
def test_the_papers_candidate_is_the_default_and_the_others_read_from_a_file(
    tmp_path, value: str
) -> None:
    assert PlanodomConfig().odometry.pair_rotation == "first"
    (tmp_path / "c.yaml").write_text(f"odometry: {{pair_rotation: {value}}}\n")
    assert PlanodomConfig.from_yaml(tmp_path / "c.yaml").odometry.pair_rotation == value


@pytest.mark.parametrize("value", ["second", "1", "true"])
def test_a_bad_value_names_file_and_field(tmp_path, value: str) -> None:
    (tmp_path / "c.yaml").write_text(f"odometry: {{pair_rotation: {value}}}\n")
    with pytest.raises(ConfigError, match=r"c\.yaml: field 'odometry\.pair_rotation'") as err:
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert "\n" not in str(err.value)
