"""Config loading: partial files keep defaults, bad files name the file and field."""

from __future__ import annotations

import pytest

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError


def test_partial_yaml_keeps_defaults(tmp_path) -> None:
    (tmp_path / "c.yaml").write_text("extraction: {}\n")
    assert PlanodomConfig.from_yaml(tmp_path / "c.yaml") == PlanodomConfig()


def test_round_trip(tmp_path) -> None:
    cfg = PlanodomConfig()
    text = cfg.to_yaml(tmp_path / "c.yaml")
    assert PlanodomConfig.from_yaml(tmp_path / "c.yaml") == cfg
    assert text == (tmp_path / "c.yaml").read_text()


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("odometry: {no_such_field: 1}\n", r"c\.yaml: field 'odometry\.no_such_field'"),
        ("nonsense_section: 3\n", r"c\.yaml: field 'nonsense_section'"),
        ("odometry: [1, 2\n", r"c\.yaml: not valid YAML"),
        ("smoothing: {fallback_start: backwards}\n", r"c\.yaml: field 'smoothing\.fallback_start'"),
        (
            "smoothing: {loop_refuse_ambiguous: maybe}\n",
            r"c\.yaml: field 'smoothing\.loop_refuse_ambiguous'",
        ),
        ("odometry: {map_trend_rescue: perhaps}\n", r"c\.yaml: field 'odometry\.map_trend_rescue'"),
        ("smoothing: {loop_map_epoch: latest}\n", r"c\.yaml: field 'smoothing\.loop_map_epoch'"),
        (
            "smoothing: {loop_candidate_aliases: on}\n",
            r"c\.yaml: field 'smoothing\.loop_candidate_aliases'",
        ),
        (
            "odometry: {pairwise_reference_time: start}\n",
            r"c\.yaml: field 'odometry\.pairwise_reference_time'",
        ),
        ("extraction: {deskew_jacobian: 3}\n", r"c\.yaml: field 'extraction\.deskew_jacobian'"),
        (
            "odometry: {refine_unmeasured: blended}\n",
            r"c\.yaml: field 'odometry\.refine_unmeasured'",
        ),
        ("extraction: {grid_max_columns: 8}\n", r"c\.yaml: field 'extraction\.grid_max_columns'"),
        ("extraction: {grid_max_rows: 2}\n", r"c\.yaml: field 'extraction\.grid_max_rows'"),
        ("extraction: {time_moments: 3}\n", r"c\.yaml: field 'extraction\.time_moments'"),
        ("planemap: {twist_estimation: yes}\n", r"c\.yaml: field 'planemap\.twist_estimation'"),
        ("planemap: {twist_map_update: raw}\n", r"c\.yaml: field 'planemap\.twist_map_update'"),
        ("planemap: {prediction: median}\n", r"c\.yaml: field 'planemap\.prediction'"),
        ("planemap: {twist_filter: yes}\n", r"c\.yaml: field 'planemap\.twist_filter'"),
        ("planemap: {kept_pose: predicted}\n", r"c\.yaml: field 'planemap\.kept_pose'"),
        (
            "smoothing: {deskew_noise: twist_change_jacobian}\nextraction: 5\n",
            r"c\.yaml: field 'extraction'",
        ),
    ],
)
def test_bad_files_name_file_and_field(tmp_path, text: str, match: str) -> None:
    (tmp_path / "c.yaml").write_text(text)
    with pytest.raises(ConfigError, match=match):
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")


def test_missing_file(tmp_path) -> None:
    with pytest.raises(ConfigError, match="missing.yaml: cannot read"):
        PlanodomConfig.from_yaml(tmp_path / "missing.yaml")


def test_jacobian_deskew_noise_switches_on_the_planes_deskew_jacobian():
    """The smoothing mode that reads Plane.deskew_jacobian makes the extraction compute it;
    every other mode leaves it off (it costs time per plane)."""
    assert PlanodomConfig().extraction.deskew_jacobian is False
    for mode in ("twist_change_jacobian", "twist_change_jacobian_net"):
        assert PlanodomConfig().updated({"smoothing.deskew_noise": mode}).extraction.deskew_jacobian
        loaded = PlanodomConfig.from_dict({"smoothing": {"deskew_noise": mode}})
        assert loaded.extraction.deskew_jacobian
    other = PlanodomConfig.from_dict({"smoothing": {"deskew_noise": "twist_change_frame_net"}})
    assert other.extraction.deskew_jacobian is False
