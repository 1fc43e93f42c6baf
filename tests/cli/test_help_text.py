"""Commands' help reflowed to the terminal (planodom.cli.help_text)."""

from __future__ import annotations

import re

import pytest
from typer.testing import CliRunner

from planodom.cli import app
from planodom.cli.help_text import reflowed


def test_reflowed_joins_lines_within_paragraphs_only():
    text = """First line
    goes on.

    Second paragraph,
    in three
    lines."""
    assert reflowed(text) == "First line goes on.\n\nSecond paragraph, in three lines."


def _description(output: str) -> list[list[str]]:
    """The paragraphs of the prose between the usage line and the first panel."""
    body = output.split("Usage:", 1)[1].split("\n", 1)[1].split("╭", 1)[0]
    paragraphs = re.split(r"\n\s*\n", body.strip("\n"))
    return [[ln.strip() for ln in p.splitlines() if ln.strip()] for p in paragraphs if p.strip()]


@pytest.mark.parametrize("command", [["run"], ["smooth"], ["simulate"], ["eval"], ["config"]])
def test_help_fills_an_80_column_terminal(command):
    """Rich wraps each paragraph greedily at 78 columns, so every line but a paragraph's
    last is longer than 60 characters; a docstring's own line breaks (at the source's
    width) leave short lines such as "bag" alone."""
    out = CliRunner().invoke(app, [*command, "--help"], env={"COLUMNS": "80"}).output
    paragraphs = _description(out)
    assert paragraphs, out
    for lines in paragraphs:
        assert all(len(line) > 60 for line in lines[:-1]), lines
