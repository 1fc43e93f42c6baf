"""The pictures of ``eval`` and ``run`` across a gap in the reference: the lines break there
(no straight chord of the reference, no increment across the gap drawn), as the metrics
leave the gap out. Checked on the lines drawn, against the poses by hand."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

import planodom.plots.errors as errors_png
import planodom.plots.run as run_plots
import planodom.plots.trajectory as trajectory_png
from planodom.cli import app
from planodom.datasets import write_tum
from planodom.geometry import transform_from_rpy_xyz
from planodom.odometry import OdometryRun

TIMES = 1.7e9 + np.arange(40) * 0.1
GT = np.stack(
    [transform_from_rpy_xyz(0, 0, 0.05 * k, 0.5 * k, np.sin(0.2 * k), 0) for k in range(40)]
)
X_AXIS = 3  # errors.png's panels: roll, pitch, yaw, x, y


@pytest.fixture
def figures(monkeypatch: pytest.MonkeyPatch) -> dict[str, Any]:
    """The figures drawn, by picture ("trajectory", "errors"), kept when saved."""
    drawn: dict[str, Any] = {}
    for module, name in ((errors_png, "errors"), (trajectory_png, "trajectory")):

        def save(fig: Any, path: Path, keep: Any = module.save, name: str = name) -> Path:
            drawn[name] = fig
            return keep(fig, path)

        monkeypatch.setattr(module, "save", save)
    return drawn


def _line(fig: Any, label: str, axis: int = 0) -> tuple[np.ndarray, np.ndarray]:
    line = next(ln for ln in fig.axes[axis].get_lines() if ln.get_label() == label)
    return np.asarray(line.get_xdata(), dtype=float), np.asarray(line.get_ydata(), dtype=float)


def test_eval_plots_break_at_a_gap_in_the_reference(tmp_path: Path, figures) -> None:
    """Reference poses 15-24 missing: the increment from pose 14 to 25 was drawn as one
    epoch's error, and both tracks joined 14 and 25 by a straight line."""
    est = np.stack([GT[k] @ transform_from_rpy_xyz(0, 0, 0, 0.01 * k, 0, 0) for k in range(40)])
    kept = np.r_[0:15, 25:40]
    write_tum(tmp_path / "gt.tum", TIMES[kept], GT[kept])
    write_tum(tmp_path / "est.tum", TIMES, est)
    args = ["eval", tmp_path / "est.tum", tmp_path / "gt.tum", "--out", tmp_path / "e"]
    result = CliRunner().invoke(app, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    # errors.png: the x error of each increment k -> k+1 of matched poses, NaN across the gap
    t, x_cm = _line(figures["errors"], "estimate", X_AXIS)
    assert len(x_cm) == len(kept) - 1
    np.testing.assert_allclose(t, TIMES[kept[1:]] - TIMES[kept[1]], atol=1e-6)
    across = 14  # the increment 14 -> 25
    assert np.isnan(x_cm[across]) and np.isfinite(np.delete(x_cm, across)).all()
    for j in np.delete(np.arange(len(kept) - 1), across):
        a, b = kept[j], kept[j + 1]
        by_hand = (np.linalg.inv(est[a]) @ est[b])[0, 3] - (np.linalg.inv(GT[a]) @ GT[b])[0, 3]
        assert x_cm[j] == pytest.approx(100.0 * by_hand, abs=1e-6)
    # trajectory.png: both tracks break between poses 14 and 25 (a NaN point), no chord
    for label in ("reference", "estimate"):
        x, y = _line(figures["trajectory"], label)
        assert len(x) == len(kept) + 1 and np.isnan(x[15]) and np.isnan(y[15]), label
        assert np.isfinite(np.delete(x, 15)).all(), label
    x, y = _line(figures["trajectory"], "reference")
    np.testing.assert_allclose(np.delete(x, 15), GT[kept, 0, 3], atol=1e-6)
    np.testing.assert_allclose(np.delete(y, 15), GT[kept, 1, 3], atol=1e-6)


def test_eval_plots_of_a_whole_reference_have_no_break(tmp_path: Path, figures) -> None:
    write_tum(tmp_path / "gt.tum", TIMES, GT)
    write_tum(tmp_path / "est.tum", TIMES, GT)
    args = ["eval", tmp_path / "est.tum", tmp_path / "gt.tum", "--out", tmp_path / "e"]
    assert CliRunner().invoke(app, [str(a) for a in args]).exit_code == 0
    assert np.isfinite(_line(figures["errors"], "estimate", X_AXIS)[1]).all()
    x, _ = _line(figures["trajectory"], "reference")
    assert len(x) == 40 and np.isfinite(x).all()


def test_run_plots_break_at_a_gap_in_the_reference(
    tmp_path: Path, figures, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Epochs 10-14 without a reference (a bag's reference gap, NaN): the reference was drawn
    with a straight chord from epoch 9 to 15; it breaks there now. The increments from or
    to those epochs have no error (NaN) and none is drawn."""
    monkeypatch.setattr(run_plots, "plot_planes", lambda path, *a, **k: Path(path))
    n = 30
    poses = np.linalg.inv(GT[0]) @ GT[:n]
    run = OdometryRun(poses, TIMES[:n], [None] * n, np.zeros(n, dtype=int))
    gt = GT[:n].copy()
    gt[10:15] = np.nan
    run_plots.write_run_plots(tmp_path, run, gt)
    x, y = _line(figures["trajectory"], "reference")
    assert len(x) == n
    assert np.isnan(x[10:15]).all() and np.isfinite(np.delete(x, range(10, 15))).all()
    np.testing.assert_allclose(x[:10], GT[:10, 0, 3], atol=1e-12)
    _, x_cm = _line(figures["errors"], "odometry", X_AXIS)
    assert np.isnan(x_cm[9:15]).all()  # the increments 9 -> 10 ... 14 -> 15
    assert np.isfinite(np.delete(x_cm, range(9, 15))).all()
