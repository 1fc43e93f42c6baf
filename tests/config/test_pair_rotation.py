"""The candidate rotation of an LDA pair (planodom.config.pair_rotation)."""

import pytest

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError


def test_the_papers_candidate_is_the_default_and_weighted_is_read_from_a_file(tmp_path) -> None:
    assert PlanodomConfig().odometry.pair_rotation == "first"
    (tmp_path / "c.yaml").write_text("odometry: {pair_rotation: weighted}\n")
    assert PlanodomConfig.from_yaml(tmp_path / "c.yaml").odometry.pair_rotation == "weighted"


@pytest.mark.parametrize("value", ["second", "1", "true"])
def test_a_bad_value_names_file_and_field(tmp_path, value: str) -> None:
    (tmp_path / "c.yaml").write_text(f"odometry: {{pair_rotation: {value}}}\n")
    with pytest.raises(ConfigError, match=r"c\.yaml: field 'odometry\.pair_rotation'") as err:
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert "\n" not in str(err.value)
