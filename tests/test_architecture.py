"""Data flows one way (DESIGN.md, The pipeline): the model stages import no I/O, renderer,
experiment runner or CLI, the renderer imports no experiment runner, CLI or plots, the low
modules (file formats, resource checks, the tone map) import nothing above them, and no
gevsim module imports itself through others (no import cycles, issue 33).

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
    "gevsim.render": ("gevsim.experiments", "gevsim.cli", "gevsim.plots"),
    # Arrows that ran back up (issue 33): low modules take plain values, and callers above them draw.
    "gevsim.resources": ("gevsim.emulation", "gevsim.render", "gevsim.io", "gevsim.experiments", "gevsim.cli"),
    "gevsim.io": ("gevsim.reconstruct", "gevsim.evaluation", "gevsim.render", "gevsim.emulation", "gevsim.plots",
                  "gevsim.experiments", "gevsim.cli"),
    "gevsim.tonemap": ("gevsim.reconstruct", "gevsim.evaluation", "gevsim.io", "gevsim.plots"),
}


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _from_module(node: ast.ImportFrom, package: str) -> str:
    """The absolute module of ``from ... import`` in ``package`` (a relative import resolved)."""
    if not node.level:
        return node.module or ""
    base = package.split(".")
    base = base[: len(base) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


def _package(path: Path, name: str) -> str:
    return name if path.name == "__init__.py" else name.rpartition(".")[0]


def imports(path: Path) -> set[str]:
    """Absolute names of every module ``path`` imports (relative imports resolved)."""
    package = _package(path, module_name(path))
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            module = _from_module(node, package)
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



# --- No import cycles (issue 33) --------------------------------------------------------------
# An import under ``if TYPE_CHECKING:`` never runs and does not count; one inside a function does.
MODULE_NAMES = {module_name(p) for p in MODULES}


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    """ids of the nodes inside ``if TYPE_CHECKING:`` (or ``typing.TYPE_CHECKING``) blocks."""
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and (
                (isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING")
                or (isinstance(node.test, ast.Attribute) and node.test.attr == "TYPE_CHECKING")):
            skip.update(id(inner) for stmt in node.body for inner in ast.walk(stmt))
    return skip


def runtime_imports(path: Path, name: str) -> set[str]:
    """The gevsim modules that module ``name`` (source ``path``) imports when it runs: ``from pkg import x``
    is the module ``pkg.x`` where there is one, else ``pkg`` (its ``__init__``); itself left out."""
    package = _package(path, name)
    tree = ast.parse(path.read_text(), filename=str(path))
    skip = _type_checking_nodes(tree)
    found = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            module = _from_module(node, package)
            found.update(f"{module}.{a.name}" if f"{module}.{a.name}" in MODULE_NAMES else module for a in node.names)
    return {m for m in found if m in MODULE_NAMES and m != name}


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of ``graph`` (module -> modules it imports) that hold a cycle:
    more than one module, or one that imports itself; each sorted (Tarjan, SIAM J. Comput. 1, 1972,
    without recursion)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        work.append((node, iter(sorted(graph.get(node, ())))))

    for root in sorted(graph):
        if root in index:
            continue
        work: list = []
        visit(root)
        while work:
            node, children = work[-1]
            for child in children:
                if child not in index:
                    visit(child)
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    parent = work[-1][0]
                    low[parent] = min(low[parent], low[node])
                if low[node] == index[node]:
                    component = []
                    while not component or component[-1] != node:
                        component.append(stack.pop())
                        on_stack.discard(component[-1])
                    if len(component) > 1 or node in graph.get(node, ()):
                        found.append(sorted(component))
    return sorted(found)


def test_the_cycle_finder_finds_cycles_and_only_cycles():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": {"e"}, "e": set(), "f": {"f", "a"}, "g": {"h"},
             "h": {"g"}}
    assert import_cycles(graph) == [["a", "b", "c"], ["f"], ["g", "h"]]
    assert import_cycles({"a": {"b", "c"}, "b": {"c"}, "c": set()}) == []
    # A long chain: no recursion limit.
    assert import_cycles({str(i): {str(i + 1)} for i in range(5000)}) == []
    assert import_cycles({**{str(i): {str(i + 1)} for i in range(5000)}, "5000": {"0"}}) == [
        sorted(str(i) for i in range(5001))]


def test_the_import_graph_counts_lazy_imports_and_not_type_checking_ones(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text("from typing import TYPE_CHECKING\nimport gevsim.errors\nif TYPE_CHECKING:\n"
                     "    from gevsim.io import atomic\nelse:\n    import numpy\n"
                     "def f():\n    from gevsim.render import basis, render_basis\n    from . import timebase\n")
    assert runtime_imports(probe, "gevsim.probe") == {"gevsim.errors", "gevsim.render.basis", "gevsim.render",
                                                      "gevsim.timebase"}


def test_no_import_cycles():
    graph = {module_name(p): runtime_imports(p, module_name(p)) for p in MODULES}
    found = import_cycles(graph)
    report = []
    for component in found:
        edges = [f"  {a} -> {b}" for a in component for b in sorted(graph[a]) if b in component]
        report.append(f"import cycle among {', '.join(component)}:\n" + "\n".join(edges))
    assert not found, "\n".join(report)


# --- Same bits on every CPU (issue 21) ---------------------------------------------------------
# numpy's transcendental ufuncs (SIMD kernels chosen at run time), libm through ``math`` (glibc's
# FMA or SSE2 variants), float ``**`` (libm pow) and BLAS products (a GEMM kernel per CPU) give
# last-bit-different results on different x86-64 CPUs. Everything after the render uses
# gevsim._portable instead. Out of scope: the renderer (Dr.Jit compiles it for the host CPU) and
# the plots.
NOT_PORTABLE_NUMPY = {
    "exp", "exp2", "expm1", "log", "log2", "log10", "log1p", "logaddexp", "logaddexp2", "sin", "cos", "tan",
    "arcsin", "arccos", "arctan", "arctan2", "sinh", "cosh", "tanh", "arcsinh", "arccosh", "arctanh", "power",
    "float_power", "hypot", "cbrt", "sinc", "geomspace", "logspace", "dot", "vdot", "inner", "outer", "matmul",
    "tensordot", "einsum", "linalg",
}
NOT_PORTABLE_MATH = {
    "exp", "expm1", "exp2", "log", "log2", "log10", "log1p", "pow", "sin", "cos", "tan", "asin", "acos", "atan",
    "atan2", "sinh", "cosh", "tanh", "asinh", "acosh", "atanh", "hypot", "erf", "erfc", "gamma", "lgamma", "cbrt",
    "dist",
}
#: Generator methods whose transforms call libm (the bits of lognormal draws differ under glibc's
#: SSE2 and FMA variants; normal, uniform, integers and poisson were measured identical).
NOT_PORTABLE_RANDOM = {"lognormal", "gamma", "standard_gamma", "beta", "weibull", "pareto", "power", "vonmises",
                       "logseries", "wald", "gumbel", "logistic", "laplace", "rayleigh", "standard_t", "chisquare",
                       "f", "noncentral_chisquare", "noncentral_f", "dirichlet", "zipf", "standard_cauchy"}
PORTABILITY_EXEMPT = ("gevsim.render", "gevsim.plots", "gevsim.experiments.study_plots")


def not_portable(path: Path, name: str | None = None) -> list[str]:
    """Calls in ``path`` whose last bits depend on the CPU."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        where = f"{name or module_name(path)}:{getattr(node, 'lineno', '?')}"
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
            lib, attr = node.value.id, node.attr
            if (lib == "np" and attr in NOT_PORTABLE_NUMPY) or (lib == "math" and attr in NOT_PORTABLE_MATH):
                found.append(f"{where} {lib}.{attr}")
        if isinstance(node, ast.Attribute) and node.attr in NOT_PORTABLE_RANDOM and isinstance(node.value, ast.Name) \
                and "rng" in node.value.id:
            found.append(f"{where} {node.value.id}.{node.attr}")
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.MatMult):
            found.append(f"{where} @")
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow) and not (
                isinstance(node.left, ast.Constant) and type(node.left.value) is int):
            found.append(f"{where} ** (write x * x, or an integer base)")
    return found


def test_the_portability_scan_finds_what_it_must(tmp_path):
    probe = tmp_path / "probe.py"
    probe.write_text("import math\nimport numpy as np\na = np.exp(1.0) + math.log(2.0) + (x @ y) + z ** 2 + 2 ** 8\n"
                     "b = rng.lognormal(0, 1) + np.sqrt(2.0) + math.floor(z)\n")
    assert len(not_portable(probe, "probe")) == 5


def test_event_and_reconstruction_paths_use_portable_arithmetic():
    bad = [hit for path in MODULES if not any(within(module_name(path), m) for m in PORTABILITY_EXEMPT)
           for hit in not_portable(path)]
    assert not bad, "use gevsim._portable instead:\n" + "\n".join(bad)
