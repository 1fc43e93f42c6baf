"""Experiment outputs: a taken folder is refused before the experiment runs, --overwrite
replaces only an earlier experiment's files, the default is a fresh timestamped folder, and
an interrupted long experiment keeps the tables of the worlds it finished."""

from __future__ import annotations

import csv

import pytest
from typer.testing import CliRunner

import planodom.experiments.generalisation as generalisation
from planodom.cli import app

runner = CliRunner()
PAPER = ["experiment", "paper", "--epochs", "4", "--levels", "0"]


def test_a_folder_with_other_files_is_refused_before_running(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    result = runner.invoke(app, [*PAPER, "--out", str(out)])
    assert result.exit_code == 2
    message = result.output.strip()
    assert message.startswith("error:") and str(out) in message and "notes.txt" in message
    assert "--overwrite" not in message  # it would refuse the folder too
    assert [p.name for p in out.iterdir()] == ["notes.txt"]
    assert (out / "notes.txt").read_text() == "keep me"
    # --overwrite does not delete a file no experiment writes
    result = runner.invoke(app, [*PAPER, "--out", str(out), "--overwrite"])
    assert result.exit_code == 2 and "notes.txt" in result.output
    assert (out / "notes.txt").read_text() == "keep me"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["paper", "--epochs", "0", "--levels", "0"], "--epochs 0: an experiment measures"),
        (["paper", "--epochs", "1", "--levels", "0"], "--epochs 1: an experiment measures"),
        (["smoothing", "--epochs", "1"], "--epochs 1: an experiment measures the steps"),
        (["consistency", "--epochs", "0"], "--epochs 0: an experiment measures the steps"),
        (["generalisation", "--worlds", "0"], "--worlds 0: expected 1 or more worlds"),
        (["generalisation", "--epochs", "1"], "--epochs 1: expected 0 (one lap) or 2 or more"),
        (["loops", "--worlds", "-2"], "--worlds -2: expected 1 or more worlds"),
        (["loops", "--epochs", "-3"], "--epochs -3: expected 0 (one lap) or 2 or more"),
    ],
)
def test_counts_that_measure_nothing_are_refused_before_a_folder_is_made(tmp_path, args, message):
    """--epochs 0 ended in an IndexError traceback, --epochs 1 in tables of NaN, and
    --worlds 0 (or fewer) wrote empty tables with exit status 0."""
    out = tmp_path / "e"
    result = runner.invoke(app, ["experiment", *args, "--out", str(out)])
    assert result.exit_code == 2, result.output
    assert result.output.strip().startswith(f"error: {message}")
    assert len(result.output.strip().splitlines()) == 1 and not out.exists()


def test_overwrite_replaces_an_earlier_experiment(tmp_path):
    out = tmp_path / "paper"
    assert runner.invoke(app, [*PAPER, "--out", str(out)]).exit_code == 0
    (out / "stale.csv").write_text("from an earlier run\n")
    again = runner.invoke(app, [*PAPER, "--out", str(out)])
    assert again.exit_code == 2 and (out / "stale.csv").exists()
    again = runner.invoke(app, [*PAPER, "--out", str(out), "--overwrite"])
    assert again.exit_code == 0, again.output
    assert not (out / "stale.csv").exists() and (out / "summary.csv").is_file()


def test_default_folder_is_new_and_linked_as_latest(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    first = runner.invoke(app, PAPER)
    second = runner.invoke(app, PAPER)
    assert first.exit_code == 0 and second.exit_code == 0, first.output + second.output
    runs = sorted(p for p in (tmp_path / "results" / "paper").iterdir() if p.name != "latest")
    assert len(runs) == 2 and all((p / "summary.csv").is_file() for p in runs)
    assert (tmp_path / "results" / "paper" / "latest").resolve() == runs[-1].resolve()


def test_a_failed_experiment_leaves_no_empty_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, ["experiment", "generalisation", "--worlds", "1", "--methods",
                                 "oracle", "--epochs", "3", "--first-world", "-1"])  # fmt: skip
    assert result.exit_code != 0
    assert not (tmp_path / "results" / "generalisation").exists() or not any(
        (tmp_path / "results" / "generalisation").iterdir()
    )


def test_interrupted_generalisation_keeps_finished_worlds(tmp_path, monkeypatch):
    real = generalisation.run_world
    calls: list[int] = []

    def fails_on_second_world(world, noise, n_epochs, *args, **kwargs):
        if n_epochs == 3:  # the untimed warm-up
            return real(world, noise, n_epochs, *args, **kwargs)
        calls.append(world.seed)
        if len(calls) > 1:
            raise KeyboardInterrupt  # the user's Ctrl-C during the second world
        return real(world, noise, n_epochs, *args, **kwargs)

    monkeypatch.setattr(generalisation, "run_world", fails_on_second_world)
    with pytest.raises(KeyboardInterrupt):
        generalisation.run_generalisation_experiment(
            tmp_path, n_worlds=2, noise_levels=[0.006], n_epochs=4, methods=("oracle",)
        )
    rows = list(csv.DictReader((tmp_path / "runs.csv").open()))
    assert [(r["world"], r["method"]) for r in rows] == [(str(calls[0]), "oracle")]
    assert (tmp_path / "summary.csv").is_file() and (tmp_path / "config.yaml").is_file()


def test_ctrl_c_in_an_experiment_names_the_tables_kept(tmp_path, monkeypatch):
    """typer ended it with a silent 130: nothing said which tables were kept, and where."""
    real = generalisation.run_world
    calls: list[int] = []

    def ctrl_c_on_second_world(world, noise, n_epochs, *args, **kwargs):
        if n_epochs == 3:  # the untimed warm-up
            return real(world, noise, n_epochs, *args, **kwargs)
        calls.append(world.seed)
        if len(calls) > 1:
            raise KeyboardInterrupt
        return real(world, noise, n_epochs, *args, **kwargs)

    monkeypatch.setattr(generalisation, "run_world", ctrl_c_on_second_world)
    out = tmp_path / "gen"
    args = ["experiment", "generalisation", "--worlds", "2", "--noise", "0.006"]
    result = runner.invoke(app, [*args, "--epochs", "4", "--methods", "oracle", "-o", str(out)])
    assert result.exit_code == 130, result.output
    lines = [line for line in result.stderr.splitlines() if line.startswith("interrupted")]
    assert lines == [f"interrupted (Ctrl-C); the tables written so far are kept in {out}"]
    rows = list(csv.DictReader((out / "runs.csv").open()))
    assert [r["world"] for r in rows] == [str(calls[0])]
