"""Base of every config section."""

from __future__ import annotations

import difflib
import typing
from typing import Any

from pydantic import BaseModel, ConfigDict, ValidationError, ValidationInfo, field_validator

from planodom.errors import ConfigValueError


def admits_bool(annotation: Any) -> bool:
    """Whether a field of this type may hold ``True`` / ``False``: it names ``bool``, ``Any``,
    a ``Literal`` of a boolean, a nested model (which checks its own fields), or no number
    type at all (pydantic then refuses a boolean by itself where it should)."""

    def names(tp: Any) -> tuple[bool, bool]:  # (admits a bool, is or holds a number)
        if tp is bool or tp is Any or isinstance(tp, bool):
            return True, False
        if isinstance(tp, type) and issubclass(tp, BaseModel):
            return True, False
        if tp is int or tp is float:
            return False, True
        found = [names(arg) for arg in typing.get_args(tp)]
        return any(b for b, _ in found), any(n for _, n in found)

    admits, numeric = names(annotation)
    return admits or not numeric


def holds_bool(value: Any) -> bool:
    """Whether ``value`` is a boolean or a list / tuple holding one (at any depth)."""
    if isinstance(value, bool):
        return True
    if isinstance(value, list | tuple):
        return any(holds_bool(v) for v in value)
    return False


def one_line(exc: ValidationError, source: str, model: type[BaseModel] | None = None) -> str:
    """pydantic's first error in one line: ``source: field 'a.b': problem, got value``.

    With the ``model`` validated, an unknown key names the nearest field of its section
    (``Delta``: did you mean 'delta'?) and a dotted key at the top (``odometry.delta``,
    as the CLI and :meth:`PlanodomConfig.updated` name fields) the nesting a file needs.
    """
    first = exc.errors()[0]
    loc = ".".join(str(x) for x in first["loc"]) or "(document)"
    got = f", got {first['input']!r:.60}" if first["type"] != "missing" else ""
    hint = "" if model is None else _unknown_key_hint(first, model)
    return f"{source}: field '{loc}': {first['msg']}{got}{hint}"


def _unknown_key_hint(error: Any, model: type[BaseModel]) -> str:
    """For an unknown key of ``model`` (at any depth): the fields it may have meant."""
    if error["type"] != "extra_forbidden" or not error["loc"]:
        return ""
    *path, key = (str(x) for x in error["loc"])
    for name in path:
        field = model.model_fields.get(name)
        annotation = None if field is None else field.annotation
        if not (isinstance(annotation, type) and issubclass(annotation, BaseModel)):
            return ""
        model = annotation
    section, _, rest = key.partition(".")
    if not path and rest and section in model.model_fields:
        return f" (a dotted name: in a file write it nested, '{section}:' then '  {rest}: ...')"
    owners = [name for name, f in model.model_fields.items() if key in _fields_of(f.annotation)]
    if not path and len(owners) == 1:  # a section's field at the top (``platform: vehicle``)
        return f" (a field of '{owners[0]}': in a file write '{owners[0]}:' then '  {key}: ...')"
    fields = list(model.model_fields)
    near = difflib.get_close_matches(key.lower(), fields, n=1, cutoff=0.6)
    return f" (did you mean '{near[0]}'?)" if near else ""


def _fields_of(annotation: Any) -> dict[str, Any]:
    """The fields of ``annotation`` when it is a model (a section), else none."""
    is_model = isinstance(annotation, type) and issubclass(annotation, BaseModel)
    return annotation.model_fields if is_model else {}


class Section(BaseModel):
    """Base of every config section: unknown keys are errors, values are validated.

    A number field refuses ``true`` / ``false`` (pydantic's lax mode would read them as
    1 / 0). A section built in code (``ExtractionConfig(mode="magic")``) or a field
    assigned a bad value raises :class:`planodom.errors.ConfigValueError` in one line
    naming the section and field; it is a ``ConfigError`` and a ``ValueError``, as
    pydantic's ``ValidationError`` is.
    """

    model_config = ConfigDict(extra="forbid", validate_assignment=True)

    def __init__(self, **data: Any) -> None:
        try:
            super().__init__(**data)
        except ValidationError as exc:
            raise ConfigValueError(one_line(exc, type(self).__name__)) from None

    # Validation of a loaded file (``model_validate``) must not pass through this
    # ``__init__``: pydantic would wrap the one-line error into a nested ValidationError.
    # The mark tells pydantic this is its own ``__init__``, as its RootModel does.
    __init__.__pydantic_base_init__ = True  # type: ignore[attr-defined]

    def __setattr__(self, name: str, value: Any) -> None:
        try:
            super().__setattr__(name, value)
        except ValidationError as exc:
            raise ConfigValueError(one_line(exc, type(self).__name__)) from None

    @field_validator("*", mode="before")
    @classmethod
    def _no_bool_for_numbers(cls, value: Any, info: ValidationInfo) -> Any:
        """Refuse ``true`` / ``false`` where the field holds numbers."""
        if info.field_name is None or not holds_bool(value):
            return value
        if not admits_bool(cls.model_fields[info.field_name].annotation):
            raise ValueError("expected a number, not a boolean")
        return value
