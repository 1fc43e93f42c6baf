"""ExtractionConfig: typed choices, range checks and cross-field checks fail at load with
one line naming the field; defaults round-trip."""

from __future__ import annotations

import pytest

from planodom.config import ExtractionConfig, PlanodomConfig
from planodom.errors import ConfigError


@pytest.mark.parametrize(
    ("section", "field"),
    [
        ({"mode": "lidr"}, "extraction.mode"),
        ({"voxel_size_m": 0.0}, "extraction.voxel_size_m"),
        ({"ransac_iterations": 0}, "extraction.ransac_iterations"),
        ({"max_planes": 0}, "extraction.max_planes"),
        ({"tolerance_floor_m": -0.01}, "extraction.tolerance_floor_m"),
        ({"range_noise_m": float("nan")}, "extraction.range_noise_m"),
        ({"plane_gap_m": float("inf")}, "extraction.plane_gap_m"),
        ({"ransac_probability": 1.5}, "extraction.ransac_probability"),
        ({"min_plane_points": 2}, "extraction.min_plane_points"),
        ({"time_windows": {"min_windows": 0}}, "extraction.time_windows.min_windows"),
        ({"time_windows": {"span_s": -1.0}}, "extraction.time_windows.span_s"),
        (
            {"time_windows": {"min_points_over_windows": "maybe"}},
            "extraction.time_windows.min_points_over_windows",
        ),
        (
            {"time_windows": {"sparse_windows_determined": "maybe"}},
            "extraction.time_windows.sparse_windows_determined",
        ),
        ({"rms_floor_m": 0.05}, "extraction.rms_floor_m"),
        ({"trace_parallel_deg": 20.0}, "extraction.trace_parallel_deg"),
        ({"min_segment_points": 30}, "extraction.min_segment_points"),
        ({"single_scanner_min_sweeps": 2}, "extraction.single_scanner_min_sweeps"),
        ({"region_azimuth_columns": True}, "extraction.region_azimuth_columns"),  # gone
        ({"max_unskewed_span_s": 0.1}, "extraction.max_unskewed_span_s"),  # now nested
        ({"organised_window_deg": 0.0}, "extraction.organised_window_deg"),
        ({"ransac_normal_agreement_deg": 90.0}, "extraction.ransac_normal_agreement_deg"),
        ({"region_noisy_pixels": "grown"}, "extraction.region_noisy_pixels"),
        ({"ransac_unjudged": "dropped"}, "extraction.ransac_unjudged"),
        ({"segmentation_reuse": "always"}, "extraction.segmentation_reuse"),
        ({"noise_estimate": "along"}, "extraction.noise_estimate"),
    ],
)
def test_bad_values_fail_at_load_naming_the_field(section, field) -> None:
    pattern = "^c\\.yaml: .*" + field.replace(".", "\\.")
    with pytest.raises(ConfigError, match=pattern) as err:
        PlanodomConfig.from_dict({"extraction": section}, source="c.yaml")
    assert "\n" not in str(err.value)


def test_defaults_and_nested_windows_round_trip() -> None:
    cfg = PlanodomConfig().updated({"extraction.time_windows": {"span_s": 0.02}})
    assert cfg.extraction.time_windows.span_s == 0.02
    assert cfg.extraction.time_windows.min_windows == 3
    again = PlanodomConfig.from_dict(cfg.model_dump(mode="python"))
    assert again == cfg
    assert ExtractionConfig().mode == "auto"
