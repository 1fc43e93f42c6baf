"""What a smoothing run counts reaches the result and ``metrics.json``."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from planodom.cli import app
from planodom.config import SmoothingConfig
from planodom.smoothing import smooth_batch
from planodom.smoothing.diagnostics import fallback_warning, smoother_metrics
from planodom.smoothing.synthetic import make_sequence
from planodom.smoothing.windowed import WindowedSmoother

NOISE = dict(sigma_rotation=1e-3, sigma_translation=0.01, sigma_normal=0.005, sigma_offset=0.01)


def _falls_back_at(monkeypatch, epoch: int, ratio: float | None = None) -> None:
    """Make every fixed-lag smoother fall back to QR right after adding ``epoch`` (as
    "auto" does when Cholesky fails), recording a split marginal of ``ratio`` if given."""
    add_epoch = WindowedSmoother.add_epoch

    def add(self, planes, relatives=()):
        pose = add_epoch(self, planes, relatives)
        if self.n_epochs - 1 == epoch:
            self._fall_back_to_qr()
            if ratio is not None:
                self.indefinite_marginals.append((epoch, ratio))
        return pose

    monkeypatch.setattr(WindowedSmoother, "add_epoch", add)


def test_the_batch_reports_its_initial_guess_fallbacks(monkeypatch) -> None:
    """Batch smoothing's windowed initial guess fell back to QR at epoch 7: the batch
    result says so (main: the count stayed in the discarded smoother)."""
    seq = make_sequence(15, seed=4, **NOISE)
    config = SmoothingConfig(window=5, delta_max=3)
    assert smooth_batch(seq.planes, seq.relatives, config).qr_fallback_epochs == []
    _falls_back_at(monkeypatch, 7)
    result = smooth_batch(seq.planes, seq.relatives, config)
    assert result.qr_fallback_epochs == [7] and result.indefinite_marginals == []
    odometry_start = config.model_copy(update={"batch_initial": "odometry"})
    assert smooth_batch(seq.planes, seq.relatives, odometry_start).qr_fallback_epochs == []


def test_smoother_metrics_are_plain_json() -> None:
    seq = make_sequence(8, seed=2, **NOISE)
    cfg = SmoothingConfig(window=5, delta_max=3, covariance_model="fitted")
    result = smooth_batch(seq.planes, seq.relatives, cfg)
    result.qr_fallback_epochs = [3, 6]
    result.indefinite_marginals = [(6, 2.5e-13)]
    out = json.loads(json.dumps(smoother_metrics(result)))
    assert out["qr_fallback_epochs"] == [3, 6]
    assert out["indefinite_marginals"] == [{"epoch": 6, "ratio": 2.5e-13}]
    assert out["graph"]["between"] == result.stats.between > 0
    assert out["graph"]["unresolved_epochs"] == result.stats.unresolved_epochs
    assert "covariance_note" not in out and "loop_factors" not in out
    assert out["covariance_model"] == "fitted"
    line = fallback_warning(result)
    assert line is not None and "epoch(s) 6 " in line and "2.5e-13" in line


@pytest.mark.parametrize("mode", ["batch", "windowed"])
def test_smooth_writes_the_fallbacks_to_metrics_json(tmp_path, monkeypatch, mode) -> None:
    _falls_back_at(monkeypatch, 3, ratio=1.5e-13)
    out = tmp_path / "s"
    args = ["smooth", "--scenario", "paper-loop", "--epochs", "6", "--noise", "0"]
    result = CliRunner().invoke(app, [*args, "--mode", mode, "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert "indefinite beyond round-off at epoch(s) 3" in " ".join(result.output.split())
    smoother = json.loads((out / "metrics.json").read_text())[f"smoothing_{mode}"]["smoother"]
    assert smoother["qr_fallback_epochs"] == [3]
    assert smoother["indefinite_marginals"] == [{"epoch": 3, "ratio": 1.5e-13}]
    assert smoother["graph"]["plane_factors"] > 0
