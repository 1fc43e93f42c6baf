"""covariances.npz: what a run computes, written and read back unchanged."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.covariances import odometry_covariances, read_covariances, write_covariances
from planodom.errors import DatasetError
from planodom.odometry import OdometryRun, RelativePose, Status


def test_round_trip(tmp_path) -> None:
    rng = np.random.default_rng(3)
    A = rng.normal(size=(4, 5, 5))
    covs = A @ A.transpose(0, 2, 1)
    results = [None] + [
        RelativePose(np.eye(4), covs[k], Status.OK if k else Status.DEGENERATE).between(k, k + 1)
        for k in range(3)
    ]
    results.append(RelativePose(np.eye(4), None, Status.UNRESOLVED).between(2, 4))
    run = OdometryRun(
        np.tile(np.eye(4), (5, 1, 1)), 1.7e9 + np.arange(5) * 0.1, results, np.zeros(5)
    )
    arrays = odometry_covariances(run)
    marginals = rng.normal(size=(5, 6, 6))
    write_covariances(tmp_path / "c.npz", arrays | {"smoothed_batch": marginals, "x": None})
    back = read_covariances(tmp_path / "c.npz")
    assert set(back) == {"times", "relative", "relative_prev", "relative_status", "smoothed_batch"}
    np.testing.assert_array_equal(back["relative"][1:4], covs[:3])
    assert np.isnan(back["relative"][[0, 4]]).all()
    np.testing.assert_array_equal(back["relative_prev"], [-1, 0, 1, 2, 2])
    assert back["relative_status"].tolist() == ["first", "degenerate", "ok", "ok", "unresolved"]
    np.testing.assert_array_equal(back["times"], run.times)
    np.testing.assert_array_equal(back["smoothed_batch"], marginals)
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(DatasetError, match="bad.npz: not a covariances archive"):
        read_covariances(tmp_path / "bad.npz")
