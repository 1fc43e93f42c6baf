"""The deskewing error in the odometry's plane covariances (planodom.config.plane_deskew_noise)."""

import pytest

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError


@pytest.mark.parametrize("mode", ["twist", "change"])
def test_off_by_default_and_on_it_asks_the_extraction_for_the_planes_jacobians(
    tmp_path, mode: str
) -> None:
    default = PlanodomConfig()
    assert default.odometry.plane_deskew_noise == "off"
    assert not default.extraction.deskew_jacobian
    (tmp_path / "c.yaml").write_text(f"odometry: {{plane_deskew_noise: {mode}}}\n")
    config = PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert config.odometry.plane_deskew_noise == mode
    assert config.extraction.deskew_jacobian
    updated = PlanodomConfig().updated({"odometry.plane_deskew_noise": mode})
    assert updated.extraction.deskew_jacobian


def test_a_bad_mode_names_file_and_field(tmp_path) -> None:
    (tmp_path / "c.yaml").write_text("odometry: {plane_deskew_noise: on}\n")
    with pytest.raises(ConfigError, match=r"c\.yaml: field 'odometry\.plane_deskew_noise'") as err:
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert "\n" not in str(err.value)
