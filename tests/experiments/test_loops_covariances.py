"""The loop experiment's ``batch+loops`` row (planodom.experiments.loops.compare_methods):
its mean NEES and the covariance model it came from under ``smoothing.covariance_model``."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.experiments.loops import compare_methods
from planodom.metrics import pose_nees
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.synthetic import make_sequence, with_deskew_jacobians


@pytest.mark.parametrize(("model", "expected"), [("auto", "sandwich"), ("fitted", "fitted")])
def test_batch_loops_row_names_the_model_of_its_nees(model: str, expected: str) -> None:
    """12 synthetic epochs of scans spread in time whose planes carry deskewing Jacobians:
    "auto" resolves to the sandwich, "fitted" stays fitted; the row's mean NEES5 is that of
    an independent batch run with the named model against the truth."""
    seq = make_sequence(12, seed=4, sigma_rotation=2e-4, sigma_translation=5e-3,
                        sigma_normal=1e-3, sigma_offset=5e-3)  # fmt: skip
    planes, relatives = with_deskew_jacobians(seq)
    gt = np.linalg.inv(seq.poses[0])[None] @ seq.poses
    cfg = PlanodomConfig().updated({"smoothing.covariance_model": model})
    rows = compare_methods(planes, relatives, gt, gt, None, cfg)
    row = next(r for r in rows if r["method"] == "batch+loops")
    assert row["covariance_model"] == expected
    named = cfg.updated({"smoothing.loop_closure": True, "smoothing.covariance_model": expected})
    res = smooth_batch(planes, relatives, named)
    assert res.covariances is not None
    nees = pose_nees(res.poses[1:], res.covariances[1:], gt[1:], range(5))
    assert row["mean_nees5"] == pytest.approx(float(np.nanmean(nees)), rel=1e-12)
