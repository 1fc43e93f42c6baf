"""The ``planodom`` command's entry point: :data:`planodom.cli.app`, ended by SIGTERM and
SIGHUP as by Ctrl-C (:func:`planodom.outputs.exit_on_termination`: no partial output
folder left behind)."""

from __future__ import annotations

from planodom.cli import app
from planodom.outputs import exit_on_termination


def main() -> None:
    """Run the ``planodom`` command line."""
    exit_on_termination()
    app()
