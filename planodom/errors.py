"""The library's exceptions: one base class, a few kinds the CLI reports in one line."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml


class PlanodomError(Exception):
    """Base of every error planodom raises on purpose (bad input, bad config, bad data)."""


class DatasetError(PlanodomError):
    """A dataset directory or file is missing, unreadable or inconsistent.

    The message always names the offending file or field.
    """


class ConfigError(PlanodomError):
    """A configuration file or value is invalid (the message names the file and field,
    or the command-line option)."""


class ConfigValueError(ConfigError, ValueError):
    """A config section built in code, or a field assigned, got an invalid value.

    Also a ``ValueError`` (as pydantic's ``ValidationError``, which it replaces by one line
    naming the section and the field), so ``except ValueError`` keeps catching it.
    """


class GeometryError(PlanodomError):
    """Input geometry is malformed (wrong shape, non-finite values, zero normals)."""


class OutputError(PlanodomError):
    """An output folder cannot be written, or writing it would destroy inputs or results.

    The message names the output folder (and the input it would clobber).
    """


class OutputExistsError(OutputError):
    """The output folder already holds data that only an explicit overwrite may replace.

    ``option`` is how the caller asks for that: ``overwrite=True`` in the library, and the
    CLI re-raises with ``--overwrite`` (:meth:`with_option`).
    """

    def __init__(self, path: Path, what: str, option: str = "overwrite=True") -> None:
        self.path, self.what, self.option = Path(path), what, option
        super().__init__(f"{path} already holds {what}; {option} replaces it")

    def with_option(self, option: str) -> OutputExistsError:
        """The same error pointing at ``option`` (e.g. a CLI flag) instead."""
        return OutputExistsError(self.path, self.what, option)


def yaml_problem(exc: Exception) -> str:
    """A YAML parser error in one line: ``line L, column C: problem`` (PyYAML's own
    message spans several lines and quotes the text around the mark)."""
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or " ".join(str(exc).split())
    where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
    return f"{where}{problem}"


class _UniqueKeyLoader(yaml.SafeLoader):
    """PyYAML's safe loader, refusing a key given twice in one mapping (PyYAML keeps the
    last silently: ``range_noise_m`` set twice in a config took the second, unnoticed)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        seen: set = set()
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":  # '<<: *anchor' may be overridden
                continue
            key = self.construct_object(key_node, deep=True)
            try:
                duplicate = key in seen
            except TypeError:  # an unhashable key: PyYAML's own error follows
                continue
            if duplicate:
                raise yaml.constructor.ConstructorError(
                    None, None, f"key {key!r} appears twice in one mapping", key_node.start_mark
                )
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


def read_yaml_file(path: Path, what: str, error: type[PlanodomError]) -> Any:
    """The YAML document in ``path``; ``error`` naming the file in one line when it cannot
    be read, is not UTF-8 text (``not a {what} file``), is not valid YAML or gives a key
    twice in one mapping."""
    try:
        return yaml.load(path.read_text(encoding="utf-8"), Loader=_UniqueKeyLoader)  # noqa: S506
    except OSError as exc:
        raise error(f"{path}: cannot read {what} file ({exc.strerror})") from None
    except UnicodeDecodeError:
        raise error(f"{path}: not a {what} file (not UTF-8 text)") from None
    except yaml.YAMLError as exc:
        raise error(f"{path}: not valid YAML ({yaml_problem(exc)})") from None
