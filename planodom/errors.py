"""The library's exceptions: one base class, a few kinds the CLI reports in one line."""

from __future__ import annotations

from pathlib import Path


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
