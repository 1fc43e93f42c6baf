"""The shared YAML reader of config, rig and scene files: one line naming the file."""

from __future__ import annotations

from pathlib import Path

import pytest

from planodom.config import PlanodomConfig
from planodom.datasets.dataset import read_rig
from planodom.errors import ConfigError, DatasetError
from planodom.yaml_files import read_yaml_file


def test_a_key_given_twice_is_refused_naming_file_line_and_key(tmp_path: Path) -> None:
    """PyYAML keeps the last of two equal keys silently: a config setting
    range_noise_m twice ran with the second value, unnoticed."""
    path = tmp_path / "my.yaml"
    path.write_text("extraction:\n  range_noise_m: 0.01\n  range_noise_m: 0.05\n")
    expected = (
        rf"^{path}: not valid YAML \(line 3, column 3: key 'range_noise_m' appears twice "
        r"in one mapping\)$"
    )
    with pytest.raises(ConfigError, match=expected):
        PlanodomConfig.from_yaml(path)
    path.write_text("epoch_rate: 10\nepoch_rate: 20\n")
    with pytest.raises(DatasetError, match=r"line 2, column 1: key 'epoch_rate' appears twice"):
        read_rig(path)


def test_merge_keys_and_equal_keys_in_different_mappings_stay_valid(tmp_path: Path) -> None:
    path = tmp_path / "a.yaml"
    path.write_text("a: &x {k: 1, j: 2}\nb:\n  <<: *x\n  k: 3\nc: {k: 4}\n")
    assert read_yaml_file(path, "test", ConfigError) == {
        "a": {"k": 1, "j": 2},
        "b": {"k": 3, "j": 2},
        "c": {"k": 4},
    }
