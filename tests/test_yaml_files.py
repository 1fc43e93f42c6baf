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


def test_yaml_1_2_booleans_keep_off_and_on_as_strings(tmp_path: Path) -> None:
    """``off`` / ``on`` / ``yes`` / ``no`` are strings (YAML 1.2), ``true`` / ``false`` are
    booleans; PyYAML's own safe loader (YAML 1.1) reads ``off`` as False."""
    path = tmp_path / "values.yaml"
    path.write_text("a: off\nb: on\nc: yes\nd: no\ne: true\nf: False\ng: offset\n")
    got = read_yaml_file(path, "test", ConfigError)
    assert got == {"a": "off", "b": "on", "c": "yes", "d": "no", "e": True, "f": False,
                   "g": "offset"}  # fmt: skip


def test_an_unquoted_off_is_an_options_off_and_a_bools_false(tmp_path: Path) -> None:
    path = tmp_path / "config.yaml"
    path.write_text("odometry:\n  split_reference: off\n  estimate_z: off\n  deskew: no\n")
    cfg = PlanodomConfig.from_yaml(path)
    assert cfg.odometry.split_reference == "off"
    assert cfg.odometry.estimate_z is False and cfg.odometry.deskew is False
