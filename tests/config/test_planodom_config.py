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
            "smoothing: {loop_candidate_reference: latest}\n",
            r"c\.yaml: field 'smoothing\.loop_candidate_reference'",
        ),
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
        (
            "odometry: {platform: car}\n",
            r"c\.yaml: field 'odometry\.platform': Input should be 'auto', 'vehicle', "
            r"'handheld' or 'unknown', got 'car'$",
        ),
        ("odometry: {platform: true}\n", r"c\.yaml: field 'odometry\.platform'.* got True$"),
        ("planemap: {twist_estimation: yes}\n", r"c\.yaml: field 'planemap\.twist_estimation'"),
        ("planemap: {twist_map_update: raw}\n", r"c\.yaml: field 'planemap\.twist_map_update'"),
        ("planemap: {prediction: median}\n", r"c\.yaml: field 'planemap\.prediction'"),
        ("planemap: {twist_filter: yes}\n", r"c\.yaml: field 'planemap\.twist_filter'"),
        ("planemap: {kept_pose: predicted}\n", r"c\.yaml: field 'planemap\.kept_pose'"),
        ("odometry: {gap_tilt: frozen}\n", r"c\.yaml: field 'odometry\.gap_tilt'"),
        ("association: {max_tilt_deg: 0}\n", r"c\.yaml: field 'association\.max_tilt_deg'"),
        ("association: {max_tilt_deg: 200}\n", r"c\.yaml: field 'association\.max_tilt_deg'"),
        (
            "odometry: {degenerate_gate_release: always}\n",
            r"c\.yaml: field 'odometry\.degenerate_gate_release'",
        ),
        (
            "odometry: {lost_narrow_seed_deg: -0.5}\n",
            r"c\.yaml: field 'odometry\.lost_narrow_seed_deg'",
        ),
        ("odometry: {gap_end_rate: mean}\n", r"c\.yaml: field 'odometry\.gap_end_rate'"),
        (
            "odometry: {untwisted_try: never}\n",
            r"c\.yaml: field 'odometry\.untwisted_try': Input should be 'suspect' or "
            r"'fewer_planes', got 'never'$",
        ),
        (
            "extraction: {seed_spans_gap_max_tilt_deg: 0}\n",
            r"c\.yaml: field 'extraction\.seed_spans_gap_max_tilt_deg'",
        ),
        (
            "extraction: {seed_spans_gap_max_tilt_deg: 120}\n",
            r"c\.yaml: field 'extraction\.seed_spans_gap_max_tilt_deg'",
        ),
        (
            "smoothing: {loop_tie_gate_limit: median}\n",
            r"c\.yaml: field 'smoothing\.loop_tie_gate_limit'",
        ),
        (
            "smoothing: {loop_tie_gate_limit: true}\n",
            r"c\.yaml: field 'smoothing\.loop_tie_gate_limit'",
        ),
        (
            "smoothing: {loop_tie_gate_limit: 0.99}\n",
            r"c\.yaml: field 'smoothing\.loop_tie_gate_limit'",
        ),
        ("odometry: {moment_after_ok: -1}\n", r"c\.yaml: field 'odometry\.moment_after_ok'"),
        ("odometry: {moment_after_ok: 2.5}\n", r"c\.yaml: field 'odometry\.moment_after_ok'"),
        (
            "odometry: {moment_extractions: some}\n",
            r"c\.yaml: field 'odometry\.moment_extractions'",
        ),
        (
            "smoothing: {deskew_noise: twist_change_jacobian}\nextraction: 5\n",
            r"c\.yaml: field 'extraction'",
        ),
    ],
)
def test_bad_files_name_file_and_field(tmp_path, text: str, match: str) -> None:
    (tmp_path / "c.yaml").write_text(text)
    with pytest.raises(ConfigError, match=match) as err:
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert "\n" not in str(err.value)  # one line


@pytest.mark.parametrize(
    ("text", "tail"),
    [
        ("odometry: {Delta: 2}\n", "got 2 (did you mean 'delta'?)"),
        ("Odometry: {delta: 2}\n", "got {'delta': 2} (did you mean 'odometry'?)"),
        ("extraction: {time_windows: {spam_s: 0.1}}\n", "got 0.1 (did you mean 'span_s'?)"),
        (  # the CLI's and updated()'s dotted names, read as one unknown key
            "odometry.delta: 2\n",
            "got 2 (a dotted name: in a file write it nested, 'odometry:' then '  delta: ...')",
        ),
        ("odometry: {xyz: 2}\n", "not permitted, got 2"),  # nothing near: no guess
        (  # a section's field at the top (it read "did you mean 'planemap'?")
            "platform: vehicle\n",
            "got 'vehicle' (a field of 'odometry': in a file write 'odometry:' then "
            "'  platform: ...')",
        ),
    ],
)
def test_an_unknown_key_names_the_field_it_may_mean(tmp_path, text: str, tail: str) -> None:
    """'Extra inputs are not permitted' alone; for a dotted key it read as if the field
    'odometry.delta' existed and were refused."""
    (tmp_path / "c.yaml").write_text(text)
    with pytest.raises(ConfigError) as err:
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert "Extra inputs are not permitted" in str(err.value)
    assert str(err.value).endswith(tail)


def test_updated_keeps_which_fields_were_set(tmp_path) -> None:
    """updated() validated a whole dump, which marked every field as set: a default and a
    user's value were one (the platform's options follow only the defaults)."""
    (tmp_path / "c.yaml").write_text("odometry: {delta: 2}\nextraction: {sweep: {period_s: 0.1}}\n")
    loaded = PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    out = loaded.updated({"odometry.pipeline": "wocsc", "smoothing.window": 7})
    assert out.odometry.model_fields_set == {"delta", "pipeline"}
    assert out.smoothing.model_fields_set == {"window"}
    assert out.extraction.model_fields_set == {"sweep"}
    assert out.extraction.sweep.model_fields_set == {"period_s"}
    assert out.association.model_fields_set == set()
    assert out.model_fields_set == {"odometry", "extraction", "smoothing"}
    whole = out.updated({"extraction.sweep": {"rotation": "ccw"}})  # a section replaced
    assert whole.extraction.sweep.model_fields_set == {"rotation"}
    assert whole.extraction.sweep.period_s == PlanodomConfig().extraction.sweep.period_s
    assert out.updated({}).model_dump() == out.model_dump()


def test_missing_file(tmp_path) -> None:
    with pytest.raises(ConfigError, match="missing.yaml: cannot read"):
        PlanodomConfig.from_yaml(tmp_path / "missing.yaml")


def test_jacobian_deskew_noise_switches_on_the_planes_deskew_jacobian():
    """The smoothing mode that reads Plane.deskew_jacobian makes the extraction compute it;
    every other mode leaves it off (it costs time per plane): the default covariance
    model ("auto") has it switched on by the batch smoothing, for its own odometry."""
    from planodom.smoothing.run import smoothing_config

    assert PlanodomConfig().extraction.deskew_jacobian is False
    assert smoothing_config(PlanodomConfig()).extraction.deskew_jacobian is True
    assert smoothing_config(PlanodomConfig(), "windowed").extraction.deskew_jacobian is False
    fitted = PlanodomConfig().updated({"smoothing.covariance_model": "fitted"})
    assert smoothing_config(fitted).extraction.deskew_jacobian is False
    for mode in ("twist_change_jacobian", "twist_change_jacobian_net"):
        changed = PlanodomConfig().updated({"smoothing.deskew_noise": mode})
        assert changed.extraction.deskew_jacobian
        loaded = PlanodomConfig.from_dict({"smoothing": {"deskew_noise": mode}})
        assert loaded.extraction.deskew_jacobian
    other = PlanodomConfig.from_dict({"smoothing": {"deskew_noise": "twist_change_frame_net"}})
    assert other.extraction.deskew_jacobian is False


def _number_fields(model: type, prefix: str = "") -> list[tuple[str, bool]]:
    """(dotted name, admits a boolean) of every leaf field of ``model`` and its sections,
    read from the annotations independently of the validator under test."""
    import typing

    from pydantic import BaseModel

    out = []
    for name, info in model.model_fields.items():
        tp = info.annotation
        if isinstance(tp, type) and issubclass(tp, BaseModel):
            out += _number_fields(tp, f"{prefix}{name}.")
            continue
        flat, stack = [], [tp]
        while stack:
            t = stack.pop()
            flat.append(t)
            stack += list(typing.get_args(t))
        if int in flat or float in flat:
            out.append((f"{prefix}{name}", bool in flat or True in flat or False in flat))
    return out


def test_a_boolean_is_refused_for_every_number_field(tmp_path) -> None:
    """`true` for an int or float field was read as 1 (pydantic's lax mode)."""
    fields = _number_fields(PlanodomConfig)
    numbers = [name for name, admits in fields if not admits]
    assert len(numbers) > 50  # the walk found the sections' fields
    for name in numbers:
        *path, leaf = name.split(".")
        nested: dict = {leaf: True}
        for key in reversed(path):
            nested = {key: nested}
        with pytest.raises(ConfigError, match=rf"^c\.yaml: field '{name}': .*boolean"):
            PlanodomConfig.from_dict(nested, source="c.yaml")
    (tmp_path / "c.yaml").write_text("association: {max_translation_m: true}\n")
    with pytest.raises(ConfigError, match=r"field 'association\.max_translation_m'.*boolean"):
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    (tmp_path / "c.yaml").write_text("association: {max_translation_m: 2}\n")
    assert PlanodomConfig.from_yaml(tmp_path / "c.yaml").association.max_translation_m == 2.0


def test_boolean_fields_still_take_booleans() -> None:
    defaults = PlanodomConfig().model_dump()
    flags = []
    for section, values in defaults.items():
        flags += [(section, k, v) for k, v in values.items() if isinstance(v, bool)]
    assert len(flags) > 5
    for section, key, value in flags:
        cfg = PlanodomConfig.from_dict({section: {key: not value}})
        assert getattr(getattr(cfg, section), key) is (not value)


def test_a_section_built_in_code_raises_one_line() -> None:
    """pydantic's ValidationError spans several lines; the library's error is one line naming
    the section and field, and still a ValueError for callers that catch that."""
    from planodom.config import AssociationConfig, ExtractionConfig
    from planodom.errors import ConfigValueError

    with pytest.raises(ConfigValueError) as info:
        AssociationConfig(max_translation_m=-1.0)
    assert isinstance(info.value, ValueError) and isinstance(info.value, ConfigError)
    assert "\n" not in str(info.value)
    assert str(info.value).startswith("AssociationConfig: field 'max_translation_m': ")
    with pytest.raises(ConfigValueError, match=r"^ExtractionConfig: field 'foo'"):
        ExtractionConfig(foo=1)
    with pytest.raises(ConfigValueError, match=r"^PlanodomConfig: field 'odometry\.x'"):
        PlanodomConfig(odometry={"x": 1})
    cfg = AssociationConfig()
    with pytest.raises(ConfigValueError, match=r"^AssociationConfig: field 'max_translation_m'"):
        cfg.max_translation_m = True
    assert cfg.max_translation_m == AssociationConfig().max_translation_m
    # a file's errors keep naming the file, not the class
    with pytest.raises(ConfigError, match=r"^c\.yaml: field 'association\.max_translation_m'"):
        PlanodomConfig.from_dict({"association": {"max_translation_m": -1}}, source="c.yaml")


def test_updated_fields_equals_updated() -> None:
    """The assignment path gives the config the full revalidation gives (the loop
    closure's bounds: numpy floats, a boolean), and refuses what it refuses."""
    import numpy as np

    base = PlanodomConfig().updated({"smoothing.loop_closure": True})
    changes = {
        "association.prior_translation_m": np.float64(0.731),
        "association.prior_rotation_deg": 4.25,
        "odometry.retry_without_prior": False,
        "odometry.refine_max_sigma_m": np.float64(0.0625),
    }
    fast, full = base.updated_fields(changes), base.updated(changes)
    assert fast == full
    assert fast.model_dump() == full.model_dump()
    assert base.association.prior_translation_m != 0.731  # the base is unchanged
    for bad in ({"association.prior_translation_m": True}, {"association.nonsense": 1.0}):
        with pytest.raises(ConfigError):
            base.updated(bad)
        with pytest.raises(ConfigError):
            base.updated_fields(bad)
    with pytest.raises(ConfigError):
        base.updated_fields({"association.prior_translation_m": -1.0})
    with pytest.raises(ConfigError):
        base.updated({"association.prior_translation_m": -1.0})


@pytest.mark.parametrize(
    ("text", "tail"),
    [
        (  # a dataset's rig.yaml given as --config: "field 'sensor_rig': Extra inputs ..."
            "sensor_rig: {name: r}\nsimulation: {}\nepoch_rate: 10.0\nsensor_origins: []\n"
            "extrinsics: []\n",
            "not a planodom config: its keys (sensor_rig, simulation, epoch_rate, "
            "sensor_origins ...) are none of the config's sections (extraction, association, "
            "odometry, planemap, smoothing, sweep_refine): a dataset's rig.yaml, which is "
            "read from the dataset folder",
        ),
        (  # a results folder's metrics.json: "field 'epochs': Extra inputs ..."
            '{"epochs": 20, "ate_rmse_m": 0.06}',
            "not a planodom config: its keys (epochs, ate_rmse_m) are none of the config's "
            "sections (extraction, association, odometry, planemap, smoothing, sweep_refine)",
        ),
    ],
)
def test_another_files_mapping_is_named_as_no_config(tmp_path, text: str, tail: str) -> None:
    (tmp_path / "c.yaml").write_text(text)
    with pytest.raises(ConfigError) as exc:
        PlanodomConfig.from_yaml(tmp_path / "c.yaml")
    assert str(exc.value) == f"{tmp_path / 'c.yaml'}: {tail}"


def test_a_section_left_empty_in_a_file_keeps_its_defaults(tmp_path) -> None:
    """``odometry:`` above keys all commented out is YAML's null: refused before with
    "field 'odometry': Input should be a valid dictionary ..., got None"."""
    path = tmp_path / "c.yaml"
    path.write_text("odometry:\n#  delta: 2\nextraction:\n  time_windows:\n  range_noise_m: 0.01\n")
    cfg = PlanodomConfig.from_yaml(path)
    expected = PlanodomConfig().updated({"extraction.range_noise_m": 0.01})
    assert cfg == expected
    path.write_text("odometry: 3\n")  # a value that is no section is still named
    with pytest.raises(ConfigError, match=r"c.yaml: field 'odometry'"):
        PlanodomConfig.from_yaml(path)
