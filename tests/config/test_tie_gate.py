"""The tie gate's limit option (config.tie_gate)."""

import pytest

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError


def test_it_is_tail_by_default_and_read_from_a_file(tmp_path) -> None:
    assert PlanodomConfig().smoothing.loop_tie_gate_limit == "tail"
    for mode in ("bulk", "tail"):
        (tmp_path / "c.yaml").write_text(f"smoothing: {{loop_tie_gate_limit: {mode}}}\n")
        assert PlanodomConfig.from_yaml(tmp_path / "c.yaml").smoothing.loop_tie_gate_limit == mode


@pytest.mark.parametrize("value", ["median", "true", "0.99"])
def test_a_bad_value_names_file_and_field(tmp_path, value: str) -> None:
    (tmp_path / "c.yaml").write_text(f"smoothing: {{loop_tie_gate_limit: {value}}}\n")
    with pytest.raises(ConfigError, match=r"c\.yaml: field 'smoothing\.loop_tie_gate_limit'") as e:
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert "\n" not in str(e.value)
