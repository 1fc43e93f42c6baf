"""The CLI's warnings for epochs whose estimated step exceeds the association's motion bounds,
and for epochs bridged because their estimate contradicted them (inconsistent)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planodom.cli import _report_beyond_bounds, _report_gaps, _report_inconsistent
from planodom.config import PlanodomConfig
from planodom.odometry import RelativePose, Status


def _chain(steps: list[tuple[float, float]]) -> np.ndarray:
    """Poses from steps of (metres along a tilted axis, degrees about another axis)."""
    axis = np.array([0.6, 0.0, 0.8])
    poses = [np.eye(4)]
    for metres, degrees in steps:
        step = np.eye(4)
        step[:3, :3] = Rotation.from_rotvec(
            np.radians(degrees) * np.array([0, 0.6, 0.8])
        ).as_matrix()
        step[:3, 3] = metres * axis
        poses.append(poses[-1] @ step)
    return np.array(poses)


def test_epochs_beyond_the_bounds_are_listed_and_warned(capsys: pytest.CaptureFixture) -> None:
    config = PlanodomConfig().updated(
        {"association.max_translation_m": 1.0, "association.max_rotation_deg": 20.0}
    )
    # epochs 1..5: within, too far, too much turn, within (just), both
    poses = _chain([(0.5, 5.0), (1.5, 0.0), (0.2, 25.0), (0.99, 19.9), (3.0, 40.0)])
    metrics: dict = {}
    times = 0.1 * np.arange(len(poses))
    _report_beyond_bounds(SimpleNamespace(poses=poses, times=times, config=config), metrics)
    assert metrics["epochs_beyond_motion_bounds"] == [2, 3, 5]
    err = capsys.readouterr().err
    assert "3 epoch(s) moved more than" in err and "epoch 2, 1.50 m, 0.0 deg" in err


def test_a_run_within_the_bounds_adds_nothing(capsys: pytest.CaptureFixture) -> None:
    metrics: dict = {}
    poses = _chain([(0.9, 10.0)] * 4)
    run = SimpleNamespace(poses=poses, times=0.1 * np.arange(5), config=PlanodomConfig())
    _report_beyond_bounds(run, metrics)
    assert metrics == {} and capsys.readouterr().err == ""


def test_a_gap_in_the_recording_widens_the_bounds(capsys: pytest.CaptureFixture) -> None:
    """Two scans dropped (0.3 s between epochs 1 and 2 at 10 Hz): a 2.5 m step over three
    periods is within 3 x 1 m; before, it was warned of as a lost track."""
    poses = _chain([(0.9, 5.0), (2.5, 15.0), (0.9, 5.0), (3.5, 0.0)])
    times = np.array([0.0, 0.1, 0.4, 0.5, 0.8])
    metrics: dict = {}
    _report_beyond_bounds(
        SimpleNamespace(poses=poses, times=times, config=PlanodomConfig()), metrics
    )
    assert metrics["epochs_beyond_motion_bounds"] == [4]  # 3.5 m over 3 periods: beyond
    assert "1 epoch(s) moved more than" in capsys.readouterr().err


def test_inconsistent_epochs_are_listed_and_warned(capsys: pytest.CaptureFixture) -> None:
    def rel(inconsistent: bool) -> RelativePose:
        status = Status.UNRESOLVED if inconsistent else Status.OK
        return RelativePose(np.eye(4), None, status, inconsistent=inconsistent)

    results = [None, rel(False), rel(True), rel(False), rel(True)]
    metrics: dict = {}
    _report_inconsistent(SimpleNamespace(results=results, config=PlanodomConfig()), metrics)
    assert metrics["inconsistent_epochs"] == [2, 4]
    assert "2 epoch(s) bridged by constant velocity (first: epoch 2)" in capsys.readouterr().err
    metrics = {}
    _report_inconsistent(SimpleNamespace(results=results[:2], config=PlanodomConfig()), metrics)
    assert metrics == {} and capsys.readouterr().err == ""


def test_gaps_in_the_epoch_times_are_warned_of(capsys: pytest.CaptureFixture) -> None:
    """An hour cut out of a recording ran 'ok' with 14 cm errors after the cut, no word."""
    times = np.array([0.0, 0.1, 0.2, 3600.3, 3600.4, 3600.5, 3600.8])
    metrics: dict = {}
    _report_gaps(SimpleNamespace(times=times), metrics)
    assert metrics["epochs_after_gaps"] == [3, 6]  # 36001 and 3 periods of 0.1 s
    assert "2 gap(s) in the epoch times (first: before epoch 3, 3600.1 s" in capsys.readouterr().err
    # jitter of a few per cent (KITTI's times) is no gap
    metrics = {}
    _report_gaps(
        SimpleNamespace(times=0.1 * np.arange(8) + [0, 0.004, 0, 0.01, 0, 0, 0, 0]), metrics
    )
    assert metrics == {} and capsys.readouterr().err == ""
