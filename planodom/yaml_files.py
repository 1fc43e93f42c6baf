"""YAML files read in one line of error: config, rig and scene files.

Kept apart from :mod:`planodom.errors` (which the ``planodom`` command imports first, while
a Ctrl-C still prints Python's traceback): PyYAML takes a tenth of a second to import.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import yaml

from planodom.errors import PlanodomError


def yaml_problem(exc: Exception) -> str:
    """A YAML parser error in one line: ``line L, column C: problem`` (PyYAML's own
    message spans several lines and quotes the text around the mark)."""
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or " ".join(str(exc).split())
    where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
    return f"{where}{problem}"


class _UniqueKeyLoader(yaml.SafeLoader):
    """PyYAML's safe loader, refusing a key given twice in one mapping (PyYAML keeps the
    last silently: ``range_noise_m`` set twice in a config took the second, unnoticed),
    with YAML 1.2's booleans: only true / false. YAML 1.1's ``off``, ``on``, ``yes``,
    ``no`` stay strings, so ``split_reference: off`` is the option's "off", not False
    (the config's bool fields still read those strings as booleans)."""

    yaml_implicit_resolvers = {
        first: [(tag, regexp) for tag, regexp in resolvers if tag != "tag:yaml.org,2002:bool"]
        for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
    }

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


_UniqueKeyLoader.add_implicit_resolver(
    "tag:yaml.org,2002:bool", re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF")
)


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
