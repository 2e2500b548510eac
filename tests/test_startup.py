"""Start-up (issue 37, item 5): listing scenes and presets and ``--help`` import none of the heavy libraries,
the lazy packages give the names they promise, and no numba kernel that plain Python calls is compiled in
every process (benchmarks/README.md, "Start-up", has the times)."""

import ast
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

import gevsim

PACKAGE = Path(gevsim.__file__).parent
HEAVY = ("matplotlib", "colour", "mitsuba", "drjit", "numba", "h5py", "scipy", "OpenEXR", "torch")
LISTINGS = f"""
import sys
import gevsim.cli
try:
    gevsim.cli.main(["--help"])
except SystemExit:
    pass
assert gevsim.cli.main(["scenes"]) == 0 and gevsim.cli.main(["presets"]) == 0
print(" ".join(sorted({{m.split(".")[0] for m in sys.modules}} & set({HEAVY!r}))))
"""


def test_help_scenes_and_presets_import_no_heavy_library():
    # Before: `gevsim scenes` imported colour-science, matplotlib, numba, h5py and scipy (12-17 s loaded).
    done = subprocess.run([sys.executable, "-c", LISTINGS], capture_output=True, text=True, check=True)
    *listing, heavy = done.stdout.splitlines()
    assert heavy.strip() == ""
    assert any(line.startswith("office ") for line in listing) and any(line.startswith("davis346 ") for line in listing)


def test_the_presets_listing_reads_what_load_preset_reads_but_the_lux_conversion():
    import dataclasses

    from gevsim.pixel.presets import listed_preset, load_preset, preset_names

    for name in preset_names():
        full, listed = load_preset(name), listed_preset(name)
        same = dataclasses.replace(full.photoreceptor,
                                   cutoff_ref_photocurrent_a=listed.photoreceptor.cutoff_ref_photocurrent_a)
        assert dataclasses.replace(full, photoreceptor=same) == listed, name


LAZY_PACKAGES = ("gevsim.render", "gevsim.io", "gevsim.optics", "gevsim.pixel")


def _type_checking_imports(package: str) -> dict[str, tuple[str, str]]:
    """name -> (module, attribute) of the ``if TYPE_CHECKING:`` imports in ``package``'s ``__init__``."""
    path = PACKAGE.parent / package.replace(".", "/") / "__init__.py"
    found = {}
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            for stmt in node.body:
                assert isinstance(stmt, ast.ImportFrom) and stmt.module
                found.update({a.asname or a.name: (stmt.module, a.name) for a in stmt.names})
    return found


@pytest.mark.parametrize("package", LAZY_PACKAGES)
def test_lazy_packages_give_what_their_type_checking_imports_say(package):
    module = importlib.import_module(package)
    promised = _type_checking_imports(package)
    assert sorted(promised) == sorted(module.__all__)
    for name, (source, attribute) in promised.items():
        assert getattr(module, name) is getattr(importlib.import_module(source), attribute), name
    assert set(promised) <= set(dir(module))
    with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
        module.no_such_name  # noqa: B018


def test_a_lazy_package_imports_a_submodule_on_attribute_access():
    code = "import gevsim.io as io, sys; print('gevsim.io.staging' in sys.modules, io.staging.__name__)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["False", "gevsim.io.staging"]


def test_lamp_names_are_colour_sciences_keys():
    colour = pytest.importorskip("colour")
    from gevsim.optics.lamps import LAMP_NAMES

    assert LAMP_NAMES == set(colour.SDS_ILLUMINANTS.keys()) | set(colour.SDS_LIGHT_SOURCES.keys())


def test_a_lamp_name_in_another_spelling_or_unknown_is_still_checked(tmp_path):
    from gevsim.errors import ConfigError
    from gevsim.render import load

    text = (PACKAGE.parent / "scenes" / "tabletop.toml").read_text()
    assert 'spectrum = "FL2"' in text
    scene = tmp_path / "tabletop.toml"
    scene.write_text(text.replace('spectrum = "FL2"', 'spectrum = "fl2"'))  # colour's lookup takes any case
    for builder in (PACKAGE.parent / "scenes").glob("tabletop*.py"):
        (tmp_path / builder.name).write_text(builder.read_text())
    load(scene)
    scene.write_text(text.replace('spectrum = "FL2"', 'spectrum = "FL22"'))
    with pytest.raises(ConfigError, match="unknown lamp spectrum 'FL22'"):
        load(scene)


# --- numba kernels called from plain Python are cached --------------------------------------------
NUMBA_DECORATORS = ("njit", "jit", "vectorize", "guvectorize")


def _numba_decorator(node: ast.FunctionDef) -> ast.expr | None:
    for d in node.decorator_list:
        target = d.func if isinstance(d, ast.Call) else d
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name in NUMBA_DECORATORS:
            return d
    return None


def _cached(decorator: ast.expr) -> bool:
    return isinstance(decorator, ast.Call) and any(
        k.arg == "cache" and isinstance(k.value, ast.Constant) and k.value.value is True for k in decorator.keywords)


def _module(path: Path, root: Path) -> str:
    parts = path.relative_to(root.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def uncached_kernels_called_from_python(root: Path) -> list[str]:
    """``file:line name`` where a function that is not a numba kernel uses a kernel compiled without
    ``cache=True`` (compiled again in every process that calls it, as ``exp_scalar`` was): by its name in
    its own module, by a name imported from there, or as an attribute of that module imported whole."""
    texts = {path: path.read_text() for path in sorted(root.rglob("*.py"))}
    uncached: dict[str, set[str]] = {}  # module -> its kernels without cache=True
    for path, text in texts.items():
        if "numba" in text:
            uncached[_module(path, root)] = {
                node.name for node in ast.walk(ast.parse(text)) if isinstance(node, ast.FunctionDef)
                and (d := _numba_decorator(node)) is not None and not _cached(d)}
    names = set().union(*uncached.values())
    found = []
    for path, text in texts.items():
        if not any(n in text for n in names):
            continue
        tree = ast.parse(text)
        visible = set(uncached.get(_module(path, root), ()))  # name -> a kernel here
        modules = {}  # alias -> module of kernels
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module:
                for a in node.names:
                    if a.name in uncached.get(node.module, ()):
                        visible.add(a.asname or a.name)
                    elif f"{node.module}.{a.name}" in uncached:
                        modules[a.asname or a.name] = f"{node.module}.{a.name}"
            elif isinstance(node, ast.Import):
                modules.update({a.asname: a.name for a in node.names if a.asname and a.name in uncached})
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef) and _numba_decorator(node) is None:
                for n in ast.walk(node):
                    if isinstance(n, ast.Name) and n.id in visible:
                        found.append(f"{path.relative_to(root.parent)}:{n.lineno} {n.id}")
                    elif isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name) and \
                            n.attr in uncached.get(modules.get(n.value.id, ""), ()):
                        found.append(f"{path.relative_to(root.parent)}:{n.lineno} {n.value.id}.{n.attr}")
    return found


def test_the_scan_finds_an_uncached_kernel_called_from_python(tmp_path):
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "m.py").write_text(
        "from numba import njit\n@njit(inline='always')\ndef k(x):\n    return x\n"
        "@njit(cache=True)\ndef c(x):\n    return k(x)\ndef f(x):\n    return float(k(x)) + c(x)\n")
    (tmp_path / "pkg" / "user.py").write_text(
        "from pkg import m\nfrom pkg.m import k as kk\ndef g(x):\n    return m.k(x) + kk(x) + m.c(x)\n"
        "def h(k):\n    return k\n")
    (tmp_path / "pkg" / "other.py").write_text("def k(x):\n    return x\ndef f(x):\n    return k(x)\n")
    assert uncached_kernels_called_from_python(tmp_path / "pkg") == [
        "pkg/m.py:9 k", "pkg/user.py:4 m.k", "pkg/user.py:4 kk"]


def test_no_uncached_kernel_is_called_from_python():
    assert uncached_kernels_called_from_python(PACKAGE) == []
