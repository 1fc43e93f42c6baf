"""The plane-map registration's weights under a led twist (planodom.config.lead_weights)."""

import pytest

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError


def test_off_by_default_and_on_it_asks_the_extraction_for_the_planes_jacobians(tmp_path) -> None:
    default = PlanodomConfig()
    assert default.planemap.lead_weights == "off"
    assert not default.extraction.deskew_jacobian
    (tmp_path / "c.yaml").write_text("planemap: {lead_weights: stated, led_bias_m: 0.001}\n")
    config = PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert config.planemap.lead_weights == "stated"
    assert config.planemap.led_bias_m == 0.001
    assert config.extraction.deskew_jacobian
    updated = PlanodomConfig().updated({"planemap.lead_weights": "stated"})
    assert updated.extraction.deskew_jacobian


@pytest.mark.parametrize(
    ("text", "field"),
    [("lead_weights: on", "lead_weights"), ("led_bias_m: -0.001", "led_bias_m")],
)
def test_a_bad_value_names_file_and_field(tmp_path, text: str, field: str) -> None:
    (tmp_path / "c.yaml").write_text(f"planemap: {{{text}}}\n")
    with pytest.raises(ConfigError, match=rf"c\.yaml: field 'planemap\.{field}'") as err:
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert "\n" not in str(err.value)


def test_unknown_asks_the_extraction_for_the_planes_time_moments(tmp_path) -> None:
    assert not PlanodomConfig().extraction.time_moments
    (tmp_path / "c.yaml").write_text("planemap: {lead_weights: unknown}\n")
    config = PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert config.planemap.lead_weights == "unknown"
    assert config.extraction.time_moments and not config.extraction.deskew_jacobian
    updated = PlanodomConfig().updated({"planemap.lead_weights": "unknown"})
    assert updated.extraction.time_moments
