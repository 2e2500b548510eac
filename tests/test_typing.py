"""Type hints: every public function and method of gevsim is annotated, and mypy (configured in
pyproject.toml) passes on the package; `make test` runs both through here."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]


def _unannotated(path: Path) -> list[str]:
    """Public functions and methods of a module missing a parameter or return annotation."""
    out = []

    def visit(body, prefix, in_class):
        for node in body:
            if isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                visit(node.body, f"{prefix}{node.name}.", True)
            elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                if node.name.startswith("_") and node.name not in ("__init__", "__call__"):
                    continue
                a = node.args
                params = a.posonlyargs + a.args + a.kwonlyargs + [p for p in (a.vararg, a.kwarg) if p]
                static = any(isinstance(d, ast.Name) and d.id == "staticmethod" for d in node.decorator_list)
                if in_class and not static and params:
                    params = params[1:]  # self / cls
                missing = [p.arg for p in params if p.annotation is None]
                if node.returns is None and node.name != "__init__":
                    missing.append("return")
                if missing:
                    out.append(f"{path.relative_to(ROOT)}:{node.lineno} {prefix}{node.name}: {', '.join(missing)}")

    visit(ast.parse(path.read_text()).body, "", False)
    return out


def test_public_functions_have_type_hints():
    """Modules named with a leading underscore are private and exempt, like private functions."""
    modules = [p for p in sorted((ROOT / "gevsim").rglob("*.py"))
               if not p.name.startswith("_") or p.name == "__init__.py"]
    missing = [m for p in modules for m in _unannotated(p)]
    assert not missing, "public functions without type hints:\n" + "\n".join(missing)


def test_mypy_passes():
    pytest.importorskip("mypy", reason="mypy is in the test extra: pip install -e '.[test]'")
    done = subprocess.run([sys.executable, "-m", "mypy"], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, done.stdout + done.stderr
