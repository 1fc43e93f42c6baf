"""Output folders: whole or nothing, never over inputs, replaced only when asked."""

from __future__ import annotations

from pathlib import Path

import pytest

from planodom.errors import OutputError, OutputExistsError
from planodom.outputs import atomic_folder, link_latest, timestamped_folder


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
