"""A dataset's poses.tum whose quaternions were written qw qx qy qz: `planodom run` scored
its estimate against a misread reference without a word; now warned, listed in
metrics.json. The estimate and the metrics are otherwise those of the reference as read."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from planodom.cli import app
from planodom.datasets import read_tum

runner = CliRunner()


def test_run_warns_of_a_reference_written_wxyz(tmp_path: Path) -> None:
    ds = tmp_path / "ds"
    result = runner.invoke(app, ["simulate", "-o", str(ds), "--epochs", "12"])
    assert result.exit_code == 0, result.output
    times, poses = read_tum(ds / "poses.tum")
    xyzw = Rotation.from_matrix(poses[:, :3, :3]).as_quat()
    rows = np.c_[times, poses[:, :3, 3], xyzw[:, [3, 0, 1, 2]]]  # w first
    clean = tmp_path / "clean"
    result = runner.invoke(app, ["run", str(ds), "-o", str(clean)])
    assert result.exit_code == 0, result.output
    assert "reference_notes" not in json.loads((clean / "metrics.json").read_text())
    (ds / "poses.tum").write_text("".join(" ".join(repr(float(v)) for v in r) + "\n" for r in rows))
    out = tmp_path / "res"
    result = runner.invoke(app, ["run", str(ds), "-o", str(out)])
    assert result.exit_code == 0, result.output
    warnings = [x for x in result.stderr.splitlines() if "read as qw qx qy qz" in x]
    assert len(warnings) == 1 and f"{ds / 'poses.tum'}: its orientations" in warnings[0]
    notes = json.loads((out / "metrics.json").read_text())["reference_notes"]
    assert notes == [warnings[0].removeprefix("warning: ")]
