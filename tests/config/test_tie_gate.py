"""The tie gate's limit option (config.tie_gate); its bad values are in test_planodom_config."""

from planodom.config import PlanodomConfig


def test_it_is_tail_by_default_and_read_from_a_file(tmp_path) -> None:
    assert PlanodomConfig().smoothing.loop_tie_gate_limit == "tail"
    for mode in ("bulk", "tail"):
        (tmp_path / "c.yaml").write_text(f"smoothing: {{loop_tie_gate_limit: {mode}}}\n")
        assert PlanodomConfig.from_yaml(tmp_path / "c.yaml").smoothing.loop_tie_gate_limit == mode
