"""Output folders: whole or nothing, never over inputs, replaced only when asked."""

from __future__ import annotations

import errno
import os
import signal
from collections.abc import Iterator
from pathlib import Path

import pytest

from planodom.errors import OutputError, OutputExistsError
from planodom.outputs import (
    TERMINATING,
    atomic_folder,
    exit_on_termination,
    link_latest,
    timestamped_folder,
    write_whole,
)


def test_failed_block_leaves_nothing(tmp_path: Path) -> None:
    target = tmp_path / "a" / "b" / "out"
    for failure in (RuntimeError("bug"), KeyboardInterrupt()):
        with pytest.raises(type(failure)), atomic_folder(target) as tmp:
            (tmp / "poses.tum").write_text("half")
            raise failure
        assert list(tmp_path.iterdir()) == []  # no folder, no partial, no created parents


def test_success_moves_into_place_and_overwrite_replaces_whole(tmp_path: Path) -> None:
    target = tmp_path / "out"
    with atomic_folder(target) as tmp:
        (tmp / "old.tum").write_text("1")
    assert (target / "old.tum").read_text() == "1"
    with pytest.raises(OutputExistsError, match="overwrite=True"), atomic_folder(target):
        pass
    with atomic_folder(target, overwrite=True) as tmp:
        (tmp / "new.tum").write_text("2")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert [p.name for p in target.iterdir()] == ["new.tum"]
    with (
        pytest.raises(OutputError, match="does not write"),
        atomic_folder(target, overwrite=True, owned=lambda p: p.name == "x"),
    ):
        pass
    assert (target / "new.tum").exists()


def test_a_folder_of_other_files_is_named_as_such_without_overwrite_too(tmp_path: Path) -> None:
    """It was 'already holds results (notes.txt); overwrite=True replaces it', and with
    overwrite=True then refused: now the true reason at once, the file untouched."""
    target = tmp_path / "out"
    target.mkdir()
    (target / "notes.txt").write_text("mine")
    for overwrite in (False, True):
        with pytest.raises(OutputError, match="holds 'notes.txt', which planodom does not") as err:
            with atomic_folder(target, overwrite=overwrite, owned=lambda p: p.suffix == ".tum"):
                pass
        assert not isinstance(err.value, OutputExistsError)
    assert [p.name for p in target.iterdir()] == ["notes.txt"]


def test_inputs_are_never_outputs(tmp_path: Path) -> None:
    (tmp_path / "ds" / "scans").mkdir(parents=True)
    for out, relation in [("ds", "is"), ("ds/scans", "lies inside"), (".", "contains")]:
        inputs = [tmp_path / "ds"]
        with (
            pytest.raises(OutputError, match=relation),
            atomic_folder(tmp_path / out, inputs=inputs),
        ):
            pass


def test_timestamped_and_latest(tmp_path: Path) -> None:
    first = timestamped_folder(tmp_path)
    first.mkdir()
    second = timestamped_folder(tmp_path)
    assert second != first and second.parent == tmp_path
    second.mkdir()
    link_latest(first)
    link_latest(second)
    assert (tmp_path / "latest").resolve() == second.resolve()


def test_a_full_disk_is_one_line_naming_the_folder_and_leaves_the_old_one(tmp_path: Path) -> None:
    """A write or close on a full disk raises an OSError naming no file: a traceback, as a
    bug, before; now the folder is named and the earlier results stay whole."""
    target = tmp_path / "out"
    with atomic_folder(target) as tmp:
        (tmp / "poses.tum").write_text("old")
    for code in (errno.ENOSPC, errno.EDQUOT):
        with (
            pytest.raises(OutputError, match=rf"out: cannot write results: {os.strerror(code)};"),
            atomic_folder(target, overwrite=True) as tmp,
        ):
            (tmp / "poses.tum").write_text("half")
            raise OSError(code, os.strerror(code))
        assert [p.name for p in tmp_path.iterdir()] == ["out"]
        assert (target / "poses.tum").read_text() == "old"
    with pytest.raises(OSError, match="Permission"), atomic_folder(tmp_path / "b"):
        raise OSError(errno.EACCES, "Permission denied")  # others as before


def test_termination_signals_end_the_block_and_leave_nothing(tmp_path: Path) -> None:
    """SIGTERM / SIGHUP killed the process in place, its .partial folder left behind."""
    saved = {sig: signal.getsignal(sig) for sig in TERMINATING}
    try:
        signal.signal(signal.SIGHUP, signal.SIG_IGN)  # as nohup leaves it
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        exit_on_termination()
        assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
        with pytest.raises(SystemExit) as ended, atomic_folder(tmp_path / "a" / "out") as tmp:
            (tmp / "poses.tum").write_text("half")
            os.kill(os.getpid(), signal.SIGTERM)
        assert ended.value.code == 128 + signal.SIGTERM
        assert list(tmp_path.iterdir()) == []
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


@pytest.fixture
def python_sigint() -> Iterator[None]:
    """Python's SIGINT handler for the test: a shell ignores SIGINT in a command started in
    the background (``nohup pytest ... &``), and Python then installs none."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, before)


@pytest.mark.usefixtures("python_sigint")
def test_ctrl_c_while_the_folder_moves_into_place_keeps_one_whole(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A Ctrl-C between the move's two renames (the earlier folder moved aside, the new one
    not yet in place) lost both: the earlier was removed, the new one deleted as partial."""
    target = tmp_path / "out"
    target.mkdir()
    (target / "poses.tum").write_text("old")
    rename = os.rename

    def rename_then_ctrl_c(src: object, dst: object) -> None:
        rename(src, dst)  # type: ignore[arg-type]
        if str(dst).endswith(".old"):
            os.kill(os.getpid(), signal.SIGINT)  # held until the move is complete

    monkeypatch.setattr(os, "rename", rename_then_ctrl_c)
    with pytest.raises(KeyboardInterrupt) as stopped:
        with atomic_folder(target, overwrite=True) as tmp:
            (tmp / "poses.tum").write_text("new")
    assert (target / "poses.tum").read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert stopped.value.__notes__ == [f"{target} was written whole before it"]


def test_ctrl_c_in_the_block_notes_what_was_kept(tmp_path: Path) -> None:
    target = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt) as stopped, atomic_folder(target):
        raise KeyboardInterrupt
    assert stopped.value.__notes__ == [f"nothing written to {target}"]


def test_a_file_is_written_whole_or_the_earlier_one_kept(tmp_path: Path) -> None:
    path = tmp_path / "summary.csv"
    path.write_text("earlier\n")

    def half_then_ctrl_c(tmp: Path) -> None:
        tmp.write_text("half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_whole(path, half_then_ctrl_c)
    assert path.read_text() == "earlier\n"
    assert [p.name for p in tmp_path.iterdir()] == ["summary.csv"]
    write_whole(path, lambda tmp: tmp.write_text("new\n"))
    assert path.read_text() == "new\n"
    assert [p.name for p in tmp_path.iterdir()] == ["summary.csv"]


@pytest.mark.usefixtures("python_sigint")
def test_a_second_ctrl_c_while_the_partial_folder_is_removed_waits_for_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import shutil

    rmtree = shutil.rmtree

    def ctrl_c_then_rmtree(path: object, ignore_errors: bool = False) -> None:
        os.kill(os.getpid(), signal.SIGINT)  # the second Ctrl-C, held
        rmtree(path, ignore_errors=ignore_errors)  # type: ignore[arg-type]

    monkeypatch.setattr(shutil, "rmtree", ctrl_c_then_rmtree)
    with pytest.raises(KeyboardInterrupt), atomic_folder(tmp_path / "out") as tmp:
        (tmp / "poses.tum").write_text("half")
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []
