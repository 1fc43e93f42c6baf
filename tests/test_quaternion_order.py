"""A TUM reference whose quaternions were written qw qx qy qz: read as valid unit
quaternions, it is told from the right order only against the estimate (the offset between
the two trajectories' orientations is constant for the right reading)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from planodom.cli import app
from planodom.datasets import write_tum
from planodom.quaternion_order import wxyz_note

runner = CliRunner()


def _drive(n: int = 120, turns: float = 1.0) -> np.ndarray:
    """A vehicle's poses (n, 4, 4) along a loop: heading through ``turns`` x 360 deg,
    small roll and pitch, 1 m steps forward."""
    k = np.arange(n)
    yaw = 2 * np.pi * turns * k / n
    euler = np.c_[0.02 * np.sin(k / 5), 0.03 * np.cos(k / 7), yaw]
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3] = Rotation.from_euler("xyz", euler).as_matrix()
    forward = poses[:, :3, 0]
    poses[1:, :3, 3] = np.cumsum(forward[:-1], axis=0)
    return poses


def _written_wxyz(poses: np.ndarray) -> np.ndarray:
    """The poses a reader taking ``x y z w`` gets from a file written ``w x y z``."""
    q = Rotation.from_matrix(poses[:, :3, :3]).as_quat()
    out = poses.copy()
    out[:, :3, :3] = Rotation.from_quat(q[:, [3, 0, 1, 2]]).as_matrix()
    return out


def _drifted(poses: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """An estimate of ``poses``: 0.05 deg per step of random-walk rotation drift, in a world
    frame turned 30 deg and moved."""
    drift = Rotation.from_rotvec(np.cumsum(rng.normal(0, np.radians(0.05), (len(poses), 3)), 0))
    est = poses.copy()
    est[:, :3, :3] = drift.as_matrix() @ poses[:, :3, :3]
    world = np.eye(4)
    world[:3, :3] = Rotation.from_euler("z", 30, degrees=True).as_matrix()
    world[:3, 3] = [5.0, -2.0, 0.3]
    return world @ est


def test_a_reference_written_wxyz_is_named_and_the_right_order_is_not() -> None:
    rng = np.random.default_rng(3)
    truth = _drive()
    est = _drifted(truth, rng)
    assert wxyz_note(est, truth, "ref.tum") is None
    note = wxyz_note(est, _written_wxyz(truth), "ref.tum")
    assert note is not None and note.startswith("ref.tum: its orientations agree")
    # an estimate written wxyz, told by swapping the two
    assert wxyz_note(truth, _written_wxyz(est), "est.tum") is not None


def test_undecided_cases_say_nothing() -> None:
    """A straight drive: both readings give a constant offset. A reference of another
    body frame (a camera's, turned 90 deg about x): neither reading does."""
    rng = np.random.default_rng(4)
    straight = _drive(turns=0.0)
    assert wxyz_note(_drifted(straight, rng), _written_wxyz(straight), "ref") is None
    truth = _drive()
    camera = truth.copy()
    camera[:, :3, :3] = truth[:, :3, :3] @ Rotation.from_euler("x", 90, degrees=True).as_matrix()
    est = _drifted(truth, rng)
    assert wxyz_note(est, camera, "ref") is None
    assert wxyz_note(est, _written_wxyz(camera), "ref") is None


def test_eval_warns_and_notes_it_in_metrics(tmp_path: Path) -> None:
    """`planodom eval` scored a perfect estimate against such a file without a word."""
    import json

    truth = _drive()
    times = np.arange(len(truth)) * 0.1
    write_tum(tmp_path / "est.tum", times, truth)
    write_tum(tmp_path / "ref.tum", times, _written_wxyz(truth))
    out = tmp_path / "ev"
    result = runner.invoke(
        app, ["eval", str(tmp_path / "est.tum"), str(tmp_path / "ref.tum"), "-o", str(out)]
    )
    assert result.exit_code == 0, result.output
    warning = [x for x in result.stderr.splitlines() if x.startswith("warning:")]
    assert len(warning) == 1 and f"{tmp_path / 'ref.tum'}: its orientations" in warning[0]
    assert json.loads((out / "metrics.json").read_text())["notes"] == [
        warning[0][len("warning: ") :]
    ]
