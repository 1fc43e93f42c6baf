"""The ``planodom`` command line: parses arguments, calls the library, prints tables.

Known failures (:class:`planodom.errors.PlanodomError`) are reported in one line, without
a traceback, and exit with status 2.
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console

from planodom.errors import PlanodomError

app = typer.Typer(
    help="Odometry from planar landmarks, smoothed with factor graphs.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
experiment_app = typer.Typer(help="Regenerate the paper's and the smoothing experiments.")
app.add_typer(experiment_app, name="experiment")

console = Console()
err_console = Console(stderr=True)


def reports_errors(func: Callable[..., Any]) -> Callable[..., Any]:
    """Turn the library's known errors into a one-line message and exit status 2."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except PlanodomError as exc:
            err_console.print(f"[bold red]error:[/] {exc}", highlight=False)
            raise typer.Exit(2) from None
        except FileExistsError as exc:
            err_console.print(f"[bold red]error:[/] {exc}", highlight=False)
            raise typer.Exit(2) from None

    return wrapper


OutDir = Annotated[Path, typer.Option("--out", "-o", help="Output directory.")]


def main() -> None:  # pragma: no cover - console entry point
    app()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
