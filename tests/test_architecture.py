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
