"""House style that keeps modules readable (developers' guide, issue 33): no module of gevsim over
400 lines, no function over 80 lines unless its docstring says why in a sentence starting
"(Over 80 lines: ...)"."""

from __future__ import annotations

import ast
from pathlib import Path

import gevsim

PACKAGE = Path(gevsim.__file__).parent
MAX_MODULE_LINES = 400
MAX_FUNCTION_LINES = 80
REASON = "(Over 80 lines:"


def long_functions(source: str) -> list[tuple[str, int]]:
    """(name, lines) of the functions of ``source`` over the limit without a stated reason."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            lines = node.end_lineno - node.lineno + 1
            if lines > MAX_FUNCTION_LINES and REASON not in (ast.get_docstring(node) or ""):
                found.append((node.name, lines))
    return found


def test_the_scan_finds_a_long_function_and_accepts_a_reason():
    body = "\n".join(f"    x{i} = {i}" for i in range(85))
    assert long_functions(f"def f():\n{body}\n") == [("f", 86)]
    assert long_functions(f'def f():\n    """{REASON} a reason.)"""\n{body}\n') == []


def test_no_module_over_400_lines():
    long = {str(p.relative_to(PACKAGE)): n for p in PACKAGE.rglob("*.py")
            if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not long, long


def test_no_function_over_80_lines_without_a_reason():
    long = {f"{p.relative_to(PACKAGE)}:{name}": n for p in sorted(PACKAGE.rglob("*.py"))
            for name, n in long_functions(p.read_text())}
    assert not long, long
