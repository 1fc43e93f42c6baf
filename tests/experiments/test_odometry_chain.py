"""experiments/odometry_chain.py: its bridged runs and their z against closed forms."""

from __future__ import annotations

import numpy as np
import pytest
from experiment_scripts import load_script


def _script():
    return load_script("odometry_chain")


def test_bridged_runs() -> None:
    status = np.array(["first", "degenerate", "ok", "degenerate", "unresolved", "degenerate"])
    status = np.r_[status, ["ok", "degenerate", "degenerate"]]
    assert _script().bridged_runs(status, 2) == [(3, 5), (7, 8)]
    assert _script().bridged_runs(status, 3) == [(3, 5)]


@pytest.mark.parametrize("velocity", ["none", "stated", "measured"])
def test_run_z_straight(velocity) -> None:
    """Along x, no rotation error: the run's x error over the sqrt of the summed variances
    of the ok step before it and its bridged steps (independent, shared or on top)."""
    status = np.array(["first", "ok", "ok", "ok"] + ["degenerate"] * 6 + ["ok"])
    n, dt, s_ok, s_cv = len(status), 0.1, 0.01, 0.2
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, 0, 3] = 0.5 * np.arange(n)
    truth = poses.copy()
    truth[4:, 0, 3] -= 0.03 * np.arange(1, n - 3)  # the bridge's error, 3 cm a step
    rel = np.full((n, 5, 5), np.nan)
    rel[1:] = np.diag([0.0, 0.0, 0.0, s_ok**2, s_ok**2])
    rel[4:10, 3, 3] = s_cv**2
    arrays = {
        "times": dt * np.arange(n), "relative": rel, "relative_status": status,
        "relative_prev": np.arange(n) - 1,
    }  # fmt: skip
    z = _script().run_z(poses, truth, arrays, (4, 9), 0.03, velocity)
    var = {
        "none": s_ok**2 + 6 * s_cv**2,
        "stated": s_ok**2 + (6 * s_cv) ** 2,
        "measured": s_ok**2 + 6 * s_cv**2 + (6 * s_ok) ** 2,
    }[velocity]
    assert z == pytest.approx(6 * 0.03 / np.sqrt(var), rel=1e-9)
