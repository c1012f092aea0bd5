"""Sizes that keep the package readable (issue 46): no module over MAX_MODULE_LINES lines, and
no function over MAX_FUNCTION_LINES lines unless its docstring says why it is long ("Long
because ..."). Measured from the source with `ast`."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "echo_data"
MAX_MODULE_LINES = 500
MAX_FUNCTION_LINES = 100
REASON = "Long because"


def long_functions(source: str, limit: int = MAX_FUNCTION_LINES) -> list[tuple[str, int]]:
    """(name, lines) of every function in `source` longer than `limit` whose docstring gives no
    reason (`REASON`)."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            n = (node.end_lineno or node.lineno) - node.lineno + 1
            if n > limit and REASON not in (ast.get_docstring(node) or ""):
                out.append((node.name, n))
    return out


def test_long_functions_are_found() -> None:
    body = "\n".join(f"    x{i} = {i}" for i in range(5))
    assert long_functions(f"def f():\n{body}\n", limit=4) == [("f", 6)]
    assert long_functions(f'def f():\n    """Long because a table."""\n{body}\n', limit=4) == []


MODULES = sorted(PACKAGE.rglob("*.py"))


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_module_size(path: Path) -> None:
    n = len(path.read_text().splitlines())
    assert n <= MAX_MODULE_LINES, f"{path.relative_to(PACKAGE)}: {n} lines (split it by job)"


def test_no_long_function_without_a_reason() -> None:
    found = {str(p.relative_to(PACKAGE)): long_functions(p.read_text()) for p in MODULES}
    assert not {k: v for k, v in found.items() if v}, "functions over 100 lines whose docstring does not say why (Long because ...)"
