"""The library's exceptions: one base class, a few kinds the CLI reports in one line."""

from __future__ import annotations


class PlanodomError(Exception):
    """Base of every error planodom raises on purpose (bad input, bad config, bad data)."""


class DatasetError(PlanodomError):
    """A dataset directory or file is missing, unreadable or inconsistent.

    The message always names the offending file or field.
    """


class ConfigError(PlanodomError):
    """A configuration file or value is invalid."""


class GeometryError(PlanodomError):
    """Input geometry is malformed (wrong shape, non-finite values, zero normals)."""
