"""Shared checks of the command line's one-line errors (exit status 2, no traceback)."""

from __future__ import annotations

from typer.testing import CliRunner

from planodom.cli import app

runner = CliRunner()


def fails(args: list[object], *words: object, absent: tuple[str, ...] = ()) -> str:
    """Run, expect exit status 2 and one line on stderr holding ``words`` and none of
    ``absent``; return it."""
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    for word in words:
        assert str(word) in lines[0], (word, lines[0])
    for word in absent:
        assert str(word) not in lines[0], (word, lines[0])
    return lines[0]
