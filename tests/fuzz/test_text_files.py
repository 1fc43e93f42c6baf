"""Fuzzing the text inputs: TUM trajectories, rig.yaml and config files. A corrupted file
either fails with one line naming the file (and the field, for rig and config values), or
reads as the clean file does (or, cut at a line, as its first poses)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from dataset_factory import random_poses
from fuzz_corruptions import (
    BAD_TOKENS,
    assert_one_line_naming,
    bit_flipped,
    fuzz,
    outcome,
    replace_line_token,
    truncated,
)
from hypothesis import given
from hypothesis import strategies as st

from planodom.config import PlanodomConfig
from planodom.datasets import read_rig, read_tum, write_tum
from planodom.errors import ConfigError, DatasetError
from planodom.rig import Rig

# --------------------------------------------------------------------------- TUM

TIMES = 1.6e9 + np.arange(6) * 0.1


def _clean_tum(tmp: Path) -> bytes:
    write_tum(tmp / "clean.tum", TIMES, random_poses(np.random.default_rng(2), 6))
    return (tmp / "clean.tum").read_bytes()


def _read_tum(tmp: Path, data: bytes):
    (tmp / "poses.tum").write_bytes(data)
    return outcome(read_tum, tmp / "poses.tum")


def assert_valid_trajectory(times: np.ndarray, poses: np.ndarray) -> None:
    assert np.all(np.isfinite(times)) and np.all(np.diff(times) > 0)
    assert np.all(np.abs(poses[:, :3, 3]) <= 1e8)
    R = poses[:, :3, :3]
    eye = np.broadcast_to(np.eye(3), R.shape)
    np.testing.assert_allclose(R @ R.transpose(0, 2, 1), eye, atol=1e-9)


@fuzz
@given(data=st.data())
def test_tum_truncated(tmp_path: Path, data: st.DataObject) -> None:
    clean = _clean_tum(tmp_path)
    cut, _ = data.draw(truncated(clean))
    t0, p0 = read_tum(tmp_path / "clean.tum")
    got = _read_tum(tmp_path, cut)
    if got is not None:  # a cut at or inside the last line read: the poses before it
        times, poses = got
        m = len(times)
        assert np.array_equal(times[: m - 1], t0[: m - 1])
        assert np.array_equal(poses[: m - 1], p0[: m - 1])


@fuzz
@given(data=st.data())
def test_tum_bit_flips(tmp_path: Path, data: st.DataObject) -> None:
    got = _read_tum(tmp_path, data.draw(bit_flipped(_clean_tum(tmp_path))))
    if got is not None:
        assert_valid_trajectory(*got)


@fuzz
@given(
    line=st.integers(1, 6),
    token=st.integers(0, 8),
    new=st.sampled_from([*BAD_TOKENS, None, "1e12", "2e18", "-5e8"]),
)
def test_tum_bad_values(tmp_path: Path, line: int, token: int, new: str | None) -> None:
    text = _clean_tum(tmp_path).decode()
    if token == 0 and new == "-5e8":
        new = "1e300"  # -5e8 s is a valid (if odd) first time
    assert _read_tum(tmp_path, replace_line_token(text, line, token, new).encode()) is None


# --------------------------------------------------------------------------- rig.yaml

CLEAN_RIG = {
    "epoch_rate": 10.0,
    "sensor_origins": [[0.5, 0.0, 1.2], [-0.5, 0.0, 1.2]],
    "motion_bounds": {"max_translation_m": 2.0, "max_rotation_deg": 30.0},
    "extrinsics": [np.eye(4).tolist()],
}
WRONG = [None, True, "abc", -1, 0, -1e-9, math.nan, math.inf, 1e400, [1, 2], [[1, 2, 3, 4]]]
WRONG += [{"a": 1}, [[math.nan, 0, 0]], [["x", 0, 0]], [[[1]]]]


def assert_valid_rig(rig: Rig) -> None:
    assert rig.platform in (None, "vehicle", "handheld")
    if rig.epoch_rate_hz is not None:
        assert math.isfinite(rig.epoch_rate_hz) and rig.epoch_rate_hz > 0
    if rig.sensor_origins is not None:
        assert rig.sensor_origins.ndim == 2 and rig.sensor_origins.shape[1] == 3
        assert np.all(np.isfinite(rig.sensor_origins))
    if rig.motion_bounds is not None:
        for v in (rig.motion_bounds.max_translation_m, rig.motion_bounds.max_rotation_deg):
            assert v is None or (math.isfinite(v) and v > 0)
    for T in rig.extrinsics:
        assert T.shape == (4, 4) and np.all(np.isfinite(T))


def _read_rig(tmp: Path, data: bytes) -> Rig | None:
    (tmp / "rig.yaml").write_bytes(data)
    rig = outcome(read_rig, tmp / "rig.yaml")
    if rig is not None:
        assert_valid_rig(rig)
    return rig


@pytest.mark.parametrize(
    "key", ["epoch_rate", "sensor_origins", "motion_bounds", "extrinsics", "platform"]
)
@pytest.mark.parametrize("value", WRONG, ids=repr)
def test_rig_wrong_values_name_file_and_field(tmp_path: Path, key: str, value: object) -> None:
    for where in (key, "motion_bounds.max_translation_m"):
        data = dict(CLEAN_RIG)
        if where == key:
            data[key] = value
        else:
            data["motion_bounds"] = {"max_translation_m": value}
        (tmp_path / "rig.yaml").write_text(yaml.safe_dump(data))
        try:
            rig = read_rig(tmp_path / "rig.yaml")
        except Exception as exc:  # checked to be the one kind below
            assert isinstance(exc, DatasetError), repr(exc)
            assert_one_line_naming(exc, tmp_path / "rig.yaml", where.split(".")[0])
        else:
            assert_valid_rig(rig)


_yaml_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=5), inner),
    max_leaves=20,
)


@fuzz
@given(changes=st.dictionaries(st.sampled_from(list(CLEAN_RIG)), _yaml_values, min_size=1))
def test_rig_random_values(tmp_path: Path, changes: dict) -> None:
    _read_rig(tmp_path, yaml.safe_dump(CLEAN_RIG | changes).encode())


@fuzz
@given(data=st.data())
def test_rig_corrupted_text(tmp_path: Path, data: st.DataObject) -> None:
    clean = yaml.safe_dump(CLEAN_RIG).encode()
    corrupt = data.draw(st.one_of(bit_flipped(clean), truncated(clean).map(lambda c: c[0])))
    _read_rig(tmp_path, corrupt)


# --------------------------------------------------------------------------- config files

_NUMERIC = [
    (f"{section}.{name}", field.annotation)
    for section, model in PlanodomConfig.model_fields.items()
    for name, field in model.annotation.model_fields.items()  # type: ignore[union-attr]
    if field.annotation in (int, float, float | None)
]
#: Values no numeric config field accepts: every threshold, count and size is >= 0.
BAD_NUMBERS = [-1, -1e-9, math.nan, math.inf, -math.inf, "abc", [1], {"a": 1}]


def _config_outcome(tmp: Path, text: bytes) -> PlanodomConfig | None:
    (tmp / "c.yaml").write_bytes(text)
    return outcome(PlanodomConfig.from_yaml, tmp / "c.yaml")


@pytest.mark.parametrize(
    "field",
    [f for f, _ in _NUMERIC],
)
def test_config_bad_numbers_name_file_and_field(tmp_path: Path, field: str) -> None:
    section, name = field.split(".")
    for value in BAD_NUMBERS:
        text = yaml.safe_dump({section: {name: value}}).encode()
        (tmp_path / "c.yaml").write_bytes(text)
        with pytest.raises(ConfigError) as err:
            PlanodomConfig.from_yaml(tmp_path / "c.yaml")
        assert_one_line_naming(err.value, tmp_path / "c.yaml", name)


@fuzz
@given(data=st.data())
def test_config_corrupted_text(tmp_path: Path, data: st.DataObject) -> None:
    clean = PlanodomConfig().to_yaml().encode()
    corrupt = data.draw(st.one_of(bit_flipped(clean), truncated(clean).map(lambda c: c[0])))
    cfg = _config_outcome(tmp_path, corrupt)
    if cfg is not None:  # a flipped digit is a valid config; it round-trips like one
        assert PlanodomConfig.from_dict(yaml.safe_load(cfg.to_yaml())) == cfg


@fuzz
@given(
    field=st.sampled_from([f for f, _ in _NUMERIC]),
    value=_yaml_values,
)
def test_config_random_values(tmp_path: Path, field: str, value: object) -> None:
    section, name = field.split(".")
    cfg = _config_outcome(tmp_path, yaml.safe_dump({section: {name: value}}).encode())
    if cfg is not None:
        got = getattr(getattr(cfg, section), name)
        assert got is None or (math.isfinite(got) and got >= 0)
