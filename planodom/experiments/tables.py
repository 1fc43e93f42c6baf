"""The experiments' results: runs and tables (lists of flat dict rows, written as Markdown
and CSV)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Generic, TypeVar

from planodom.outputs import write_whole
from planodom.results import write_rows

Rows = Sequence[Mapping[str, Any]]
RunT = TypeVar("RunT")


@dataclass
class ExperimentResult(Generic[RunT]):
    """An experiment's runs, its tables (name -> rows, e.g. "summary") and written files."""

    runs: list[RunT]
    tables: dict[str, list[dict[str, Any]]]
    files: dict[str, Path] = field(default_factory=dict)


def markdown_table(rows: Rows, digits: int = 4) -> str:
    """A GitHub Markdown table of flat dict rows (floats in ``digits`` significant digits)."""
    if not rows:
        return ""
    cols = list(rows[0])

    def fmt(v: object) -> str:
        return f"{v:.{digits}g}" if isinstance(v, float) else str(v)

    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(fmt(r[c]) for c in cols) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def write_tables(
    out: Path,
    tables: Mapping[str, Rows],
    markdown: Mapping[str, Callable[[Rows], str]] | None = None,
) -> dict[str, Path]:
    """``<name>.md`` and ``<name>.csv`` in ``out`` per table; returns their paths, keyed
    ``<name>_md`` and ``<name>_csv``. ``markdown`` maps a table name to its own Markdown
    layout (default :func:`markdown_table`). Each file is written whole
    (:func:`planodom.outputs.write_whole`): a Ctrl-C keeps the earlier one."""
    files: dict[str, Path] = {}
    for name, rows in tables.items():
        files[f"{name}_md"] = out / f"{name}.md"
        files[f"{name}_csv"] = out / f"{name}.csv"
        text = (markdown or {}).get(name, markdown_table)(rows)
        write_whole(files[f"{name}_md"], lambda tmp: tmp.write_text(text))  # noqa: B023 (called at once)
        write_whole(files[f"{name}_csv"], lambda tmp: write_rows(tmp, rows))  # noqa: B023
    return files
