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
    except (KeyboardInterrupt, ImportError) as exc:
        if not interrupted_import(exc):
            raise
        sys.stderr.write("interrupted (Ctrl-C) while starting: nothing was read or written\n")
        raise SystemExit(INTERRUPTED) from None
    command_line()


def interrupted_import(exc: BaseException) -> bool:
    """Whether ``exc`` is a Ctrl-C, or an ImportError a Ctrl-C caused: a compiled module's
    initialisation interrupted (pybind11's ``ImportError: initialization failed``, seen
    for open3d, raised from the KeyboardInterrupt)."""
    seen: set[int] = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        if not isinstance(exc, ImportError):
            return False
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__  # type: ignore[assignment]
    return False
