"""Commands' help as prose the terminal wraps.

Typer's rich help keeps a docstring's single line breaks, so a docstring wrapped at the
source's 92 columns is cut again at a terminal's 80 ("... (read with the" / "bag" /
"options)"). Its markdown mode would reflow, but reads ``<timestamp>`` and ``*`` in the
options' help as markup, so the paragraphs are joined here instead.
"""

from __future__ import annotations

import inspect

import typer


def reflowed(text: str) -> str:
    """``text`` with the lines of each paragraph (blank-line separated) joined by spaces."""
    paragraphs = inspect.cleandoc(text).split("\n\n")
    return "\n\n".join(" ".join(line.strip() for line in p.splitlines()) for p in paragraphs)


def reflow_help(app: typer.Typer) -> None:
    """Set every command's help (its docstring when none was given) of ``app`` and of its
    sub-apps to :func:`reflowed` text."""
    for info in app.registered_commands:
        text = info.help or inspect.getdoc(info.callback)
        if isinstance(text, str) and text:
            info.help = reflowed(text)
    for group in app.registered_groups:
        if group.typer_instance is not None:
            reflow_help(group.typer_instance)
