"""Shared pieces of the fuzz suite: corruptions of a file's bytes and the two outcomes
allowed for a corrupted input (a one-line PlanodomError naming the file, or a result)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from planodom.errors import PlanodomError

#: Tokens that must never be read as a value of an ASCII point or pose line.
BAD_TOKENS = ["foo", "nan", "NaN", "inf", "-inf", "1e300", "-1e300", "1e30", "0x1F", "1,5"]


def outcome(read: Callable[[Path], Any], path: Path) -> Any:
    """``read(path)``, or None when it raised a PlanodomError that is one line naming
    ``path``; any other exception propagates (a traceback: a bug)."""
    try:
        return read(path)
    except PlanodomError as exc:
        assert_one_line_naming(exc, path)
        return None


def assert_one_line_naming(exc: BaseException, path: Path, *names: str) -> None:
    message = str(exc)
    assert "\n" not in message, message
    assert str(path) in message, f"{path} not in {message!r}"
    for name in names:
        assert name in message, f"{name!r} not in {message!r}"


@st.composite
def truncated(draw: st.DrawFn, data: bytes) -> tuple[bytes, int]:
    """``data`` cut at a random length (and the length)."""
    k = draw(st.integers(0, len(data) - 1))
    return data[:k], k


@st.composite
def bit_flipped(draw: st.DrawFn, data: bytes, start: int = 0) -> bytes:
    """``data`` with one to three bits flipped at or after byte ``start``."""
    out = bytearray(data)
    for bit in draw(st.lists(st.integers(start * 8, len(data) * 8 - 1), min_size=1, max_size=3)):
        out[bit // 8] ^= 1 << (bit % 8)
    return bytes(out)


def replace_line_token(text: str, line: int, token: int, new: str | None) -> str:
    """``text`` with token ``token`` of line ``line`` replaced by ``new`` (None: deleted;
    a token index past the end appends ``new``)."""
    lines = text.split("\n")
    tokens = lines[line].split()
    if token >= len(tokens):
        tokens.append(new or "1")
    elif new is None:
        del tokens[token]
    else:
        tokens[token] = new
    lines[line] = " ".join(tokens)
    return "\n".join(lines)


#: Settings of every fuzz test: examples rewrite one file in ``tmp_path`` (so the
#: function-scoped fixture is fine), derandomised by the profile in conftest.py.
fuzz = settings(suppress_health_check=[HealthCheck.function_scoped_fixture])
