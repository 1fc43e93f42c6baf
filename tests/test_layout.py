"""The code stays readable: no module over 450 lines, no function over 80 (numba kernels
excepted: a compiled loop reads best in one piece), as the redesign set out."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = sorted(
    [*ROOT.joinpath("planodom").rglob("*.py"), *ROOT.joinpath("factors").rglob("*.py")]
)
MAX_MODULE_LINES = 450
MAX_FUNCTION_LINES = 80


def _is_numba_kernel(node: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    for dec in node.decorator_list:
        target = dec.func if isinstance(dec, ast.Call) else dec
        if "njit" in ast.unparse(target) or "numba.jit" in ast.unparse(target):
            return True
    return False


def long_functions(source: str) -> list[tuple[str, int]]:
    """(name, lines) of every function longer than the limit, kernels excepted."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) and not _is_numba_kernel(node):
            n = (node.end_lineno or node.lineno) - node.lineno + 1
            if n > MAX_FUNCTION_LINES:
                out.append((node.name, n))
    return out


def test_the_checker_sees_a_long_function_and_spares_kernels():
    body = "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION_LINES))
    assert long_functions(f"def f():\n{body}\n") == [("f", MAX_FUNCTION_LINES + 1)]
    assert long_functions(f"@numba.njit(cache=True)\ndef k():\n{body}\n") == []


@pytest.mark.parametrize("path", SOURCES, ids=lambda p: str(p.relative_to(ROOT)))
def test_module_and_function_sizes(path: Path):
    source = path.read_text()
    assert source.count("\n") <= MAX_MODULE_LINES, f"{path.name}: over {MAX_MODULE_LINES} lines"
    assert long_functions(source) == [], f"{path.name}: functions over {MAX_FUNCTION_LINES} lines"
