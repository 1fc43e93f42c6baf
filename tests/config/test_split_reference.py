"""A refinement tried again against its reference extracted again (config.split_reference)."""

import pytest

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError


def test_it_is_off_by_default_and_read_from_a_file(tmp_path) -> None:
    assert PlanodomConfig().odometry.split_reference == "off"
    for mode in ("split", "any", "off"):
        (tmp_path / "c.yaml").write_text(f"odometry: {{split_reference: '{mode}'}}\n")
        assert PlanodomConfig.from_yaml(tmp_path / "c.yaml").odometry.split_reference == mode


@pytest.mark.parametrize("value", ["maybe", "true", "2", "[split]"])
def test_a_bad_value_names_file_and_field(tmp_path, value: str) -> None:
    (tmp_path / "c.yaml").write_text(f"odometry: {{split_reference: {value}}}\n")
    with pytest.raises(ConfigError, match=r"c\.yaml: field 'odometry\.split_reference'") as err:
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert "\n" not in str(err.value)
