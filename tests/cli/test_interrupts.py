"""Ctrl-C during a command: one line, exit status 130, the earlier results kept whole."""

from __future__ import annotations

import os
import signal
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from planodom.cli import app

runner = CliRunner()


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("sim") / "ds"
    result = runner.invoke(app, ["simulate", "--out", str(path), "--epochs", "6"])
    assert result.exit_code == 0, result.output
    return path


@pytest.fixture
def ctrl_c_mid_run(monkeypatch: pytest.MonkeyPatch) -> Iterator[Callable[[], None]]:
    """Arms the next run: a real SIGINT (a terminal's Ctrl-C) sent to this process from
    the odometry's progress call after its second epoch. Python's handler is installed
    for the test: a shell ignores SIGINT in a command started in the background (``nohup
    pytest ... &``), and Python then installs none."""
    import planodom.odometry as odometry

    real = odometry.run_odometry

    def run_odometry(data, cfg, rig, progress):  # type: ignore[no-untyped-def]
        def step(k: int, n: int) -> None:
            progress(k, n)
            if k == 2:
                os.kill(os.getpid(), signal.SIGINT)

        return real(data, cfg, rig, progress=step)

    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield lambda: monkeypatch.setattr(odometry, "run_odometry", run_odometry)
    finally:
        signal.signal(signal.SIGINT, before)


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


def _interrupted(*args: object) -> list[str]:
    """Run, expect exit status 130 and no traceback; the non-blank lines of stderr."""
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 130, result.output
    assert "Traceback" not in result.output
    return [line for line in result.stderr.splitlines() if line.strip()]


def test_ctrl_c_mid_run_is_one_line_and_keeps_the_earlier_results(
    simulated: Path, tmp_path: Path, ctrl_c_mid_run: Callable[[], None]
) -> None:
    """A Ctrl-C ended the run with typer's silent 130: no word of what became of --out."""
    out = tmp_path / "res"
    result = runner.invoke(app, ["run", str(simulated), "--out", str(out)])
    assert result.exit_code == 0, result.output
    before = _snapshot(out)
    ctrl_c_mid_run()
    lines = _interrupted("run", simulated, "--out", out, "--overwrite")
    kept = f"interrupted (Ctrl-C); nothing written to {out} (the folder there is kept as it was)"
    assert lines == [kept]
    assert _snapshot(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"]  # no partial folder left

    new = tmp_path / "new" / "res"
    assert _interrupted("run", simulated, "--out", new) == [
        f"interrupted (Ctrl-C); nothing written to {new}"
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"]  # nor the parent made for it


def test_an_import_cut_short_by_ctrl_c_is_an_interrupt(
    simulated: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A Ctrl-C inside a compiled module's initialisation arrives as pybind11's
    ``ImportError: initialization failed`` (raised from the KeyboardInterrupt): a traceback
    and exit status 1 before."""
    import planodom.odometry as odometry

    def run_odometry(*args: object, **kwargs: object) -> None:
        raise ImportError("initialization failed") from KeyboardInterrupt()

    monkeypatch.setattr(odometry, "run_odometry", run_odometry)
    out = tmp_path / "res"
    assert _interrupted("run", simulated, "--out", out) == [
        f"interrupted (Ctrl-C); nothing written to {out}"
    ]
    assert list(tmp_path.iterdir()) == []
