"""The ``planodom`` command's entry point, which imports nothing heavy itself.

Importing the command line (typer, numpy, scipy, open3d: a second or two) is the first
thing the command does; a Ctrl-C then printed Python's ``KeyboardInterrupt`` traceback
from inside numpy's import and ended with status -2. Here it ends as during a command
(:func:`planodom.cli.common.reports_errors`): one line and exit status 130.
"""

from __future__ import annotations

import sys

#: The exit status of a command ended by Ctrl-C: 128 + SIGINT, the shell's status of a
#: process the signal kills (and typer's).
INTERRUPTED = 130


def main() -> None:
    """Run the ``planodom`` command line (:func:`planodom.cli.main.main`)."""
    try:
        from planodom.cli.main import main as command_line
    except KeyboardInterrupt:
        sys.stderr.write("interrupted (Ctrl-C) while starting: nothing was read or written\n")
        raise SystemExit(INTERRUPTED) from None
    command_line()
