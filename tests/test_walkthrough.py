"""experiments/walkthrough.py runs at small size and draws its pictures."""

from __future__ import annotations

from experiment_scripts import load_script
from plot_checks import assert_nontrivial_png


def test_walkthrough_runs(tmp_path, capsys) -> None:
    module = load_script("walkthrough")
    files = module.main(tmp_path, epochs=4)
    for path in files.values():
        assert_nontrivial_png(path)
    text = capsys.readouterr().out
    assert "5. refined pose (status ok)" in text  # noise 6 mm: the pair is resolved
    # the refined yaw agrees with the truth to 0.05 deg
    yaw = next(line for line in text.splitlines() if "yaw deg" in line).split()
    assert abs(float(yaw[2]) - float(yaw[-1].rstrip(")"))) < 0.05
