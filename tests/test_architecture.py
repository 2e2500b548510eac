"""Data flows one way (DESIGN.md, The pipeline): the model stages import no I/O, renderer,
experiment runner or CLI, and the renderer imports no experiment runner or CLI.

The imports are read from the source with ``ast`` (every ``import`` and ``from ... import``,
at module level or inside functions), so a lazy import counts too.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import gevsim

PACKAGE = Path(gevsim.__file__).parent

#: stage package -> packages it must not import.
FORBIDDEN = {
    "gevsim.events": ("gevsim.io", "gevsim.render", "gevsim.experiments", "gevsim.cli"),
    "gevsim.pixel": ("gevsim.io", "gevsim.render", "gevsim.experiments", "gevsim.cli"),
    "gevsim.reconstruct": ("gevsim.io", "gevsim.render", "gevsim.experiments", "gevsim.cli"),
    "gevsim.render": ("gevsim.experiments", "gevsim.cli"),
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports(path: Path) -> set[str]:
    """Absolute names of every module ``path`` imports (relative imports resolved)."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module
            found.add(module)
            found.update(f"{module}.{alias.name}" for alias in node.names)
    return found


def within(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


MODULES = sorted(PACKAGE.rglob("*.py"))


def test_the_walk_sees_every_stage():
    names = {module_name(p) for p in MODULES}
    for stage in FORBIDDEN:
        assert stage in names
    # The resolver itself: a relative import inside a stage resolves to an absolute name.
    assert "gevsim.events.types" in imports(PACKAGE / "events" / "__init__.py")


@pytest.mark.parametrize("stage", sorted(FORBIDDEN))
def test_stage_imports_flow_one_way(stage):
    bad = []
    for path in MODULES:
        if not within(module_name(path), stage):
            continue
        for imported in imports(path):
            for forbidden in FORBIDDEN[stage]:
                if within(imported, forbidden):
                    bad.append(f"{module_name(path)} imports {imported}")
    assert not bad, "\n".join(sorted(set(bad)))
