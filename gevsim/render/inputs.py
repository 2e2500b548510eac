"""The files a scene is made of, and their content hash: what a result depends on besides its config.

A scene is its manifest (with every manifest it ``extends``), its builder (a
Python file) and every file the builder loads: textures, meshes, tables, helper
modules. Everything computed from a scene (the render cache, study runs, dataset
sequences) carries a hash of these files' contents in its key
(:func:`scene_digest`, :func:`files_digest`), so editing any of them makes it be
computed again.

The builder's files are found by running it (:func:`build_shapes`) and recording:

- every file Python opens for reading while the builder is imported and
  ``build(options)`` runs (``open``, ``numpy.load``, Pillow, imageio, helper
  modules it imports: Python's ``open`` audit event), except files of the Python
  installation (standard library, site-packages), of any other folder on ``sys.path``
  (``PYTHONPATH``, ``.pth`` files: libraries, unless the folder holds the builder) and
  gevsim's own modules;
- every module the builder's import statements name, and theirs in turn, as
  imported (``sys.modules``): found in every build, not only the first one in a
  process that imports them; what an earlier build in the process found stays
  listed, so a scene's digest does not change within a process;
- every string in the returned Mitsuba dict that names an existing file
  (``filename`` of bitmap textures, meshes, spectra), relative to the
  builder's folder or the working directory, or absolute;
- every string constant in the builder's source and every string of the
  manifest's ``[scene] options`` that names a file relative to the builder's
  (or the manifest's) folder: this catches files that Mitsuba's C++ code opens
  itself, such as ``mi.Bitmap("wood.png")``, which Python never sees.

A file reached in none of these ways (a name computed at run time and opened by
C++ code) is not found: name it in the returned dict or open it from Python.
"""

from __future__ import annotations

import ast
import contextlib
import functools
import hashlib
import importlib.util
import json
import os
import site
import sys
import sysconfig
import threading
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

from gevsim.errors import ConfigError
from gevsim.render.input_files import sha256_of
from gevsim.render.manifest import SceneManifest
from gevsim.render.manifest_checks import call_build
from gevsim.render.xml_scene import is_xml, load_xml_objects, xml_inputs

_local = threading.local()
_hook_lock = threading.Lock()
_hooked = False
_memo_lock = threading.Lock()
#: (builder, options) -> (stat signatures of the files found, the files found).
_found: dict[tuple[str, str], tuple[tuple, tuple[Path, ...]]] = {}
#: (builder, options) -> every file a build of it found in this process (issue 24 #7).
_ever_found: dict[tuple[str, str], set[Path]] = {}
#: (path, inode, size, mtime_ns) -> sha256 of the contents.
_hashes: dict[tuple, str] = {}
_WRITE_FLAGS = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_APPEND
_SYSTEM = ("/dev/", "/proc/", "/sys/")


def _audit(event: str, args: tuple) -> None:
    """Audit hook: note files opened for reading by this thread while it records."""
    if event != "open":
        return
    found = getattr(_local, "found", None)
    if found is None:
        return
    try:
        path, mode, flags = args
        if isinstance(path, int):
            return
        if isinstance(mode, str) and any(c in mode for c in "wax+"):
            return
        if mode is None and isinstance(flags, int) and flags & _WRITE_FLAGS:
            return
        found.append(path)
    except Exception:  # an audit hook must never break the call it watches
        return


@contextlib.contextmanager
def _recording() -> Iterator[list]:
    """Collect the paths this thread opens for reading inside the block."""
    global _hooked
    with _hook_lock:
        if not _hooked:
            sys.addaudithook(_audit)  # for the life of the process; it does nothing unless recording
            _hooked = True
    outer = getattr(_local, "found", None)
    found: list[str] = []
    _local.found = found
    try:
        yield found
    finally:
        _local.found = outer
        if outer is not None:
            outer.extend(found)


@functools.cache
def _installed_roots() -> tuple[str, ...]:
    """Folders of the Python installation: files there are not scene inputs."""
    roots = {sys.prefix, sys.base_prefix, sys.exec_prefix, sys.base_exec_prefix}
    paths = sysconfig.get_paths()
    roots.update(paths[k] for k in ("stdlib", "platstdlib", "purelib", "platlib") if k in paths)
    with contextlib.suppress(Exception):
        roots.update(site.getsitepackages())
    with contextlib.suppress(Exception):
        roots.add(site.getusersitepackages())
    return tuple(sorted(os.path.join(os.path.realpath(r), "") for r in roots if r))


@functools.cache
def _gevsim_root() -> str:
    import gevsim

    return os.path.join(os.path.realpath(Path(gevsim.__file__).parent), "")


def _library_roots(scene_dir: Path) -> tuple[str, ...]:
    """The folders on ``sys.path`` other than the scene's own or one above it: where libraries imported from
    ``PYTHONPATH`` or ``.pth`` files live. A library a builder imports opens its files on first import only,
    so counting them made a scene's digest change between a process's first and second build."""
    scene = os.path.join(os.path.realpath(scene_dir), "")
    roots = (os.path.join(os.path.realpath(entry), "") for entry in sys.path if entry and os.path.isdir(entry))
    return tuple(sorted({r for r in roots if not scene.startswith(r)}))


def _is_input(path: str, libraries: tuple[str, ...] = ()) -> bool:
    """Whether a file Python opened while building counts as a scene input (``libraries``: more folders
    that hold none, :func:`_library_roots`)."""
    if path.startswith(_SYSTEM) or path.startswith(_installed_roots()) or "__pycache__" in path:
        return False
    if libraries and path.startswith(libraries):
        return False
    if path.startswith(_gevsim_root()) and path.endswith((".py", ".pyc")):
        return False  # gevsim's own code: its version is in the keys that need it
    return os.path.isfile(path)


def _named_files(strings: Iterable, bases: Iterable[Path]) -> set[Path]:
    """The existing files that ``strings`` name: absolute, or relative to one of ``bases``."""
    bases = tuple(bases)
    out = set()
    for s in strings:
        if isinstance(s, os.PathLike):
            s = os.fspath(s)
        if not isinstance(s, str) or not s or len(s) > 4096 or "\n" in s or "\0" in s:
            continue
        path = Path(s).expanduser()
        for candidate in (path,) if path.is_absolute() else (b / path for b in bases):
            try:
                if candidate.is_file():
                    out.add(candidate.resolve())
                    break
            except OSError:
                continue
    return out


def _strings(obj) -> Iterator:
    """Every string (or path) inside nested dicts, lists and tuples."""
    if isinstance(obj, (str, os.PathLike)):
        yield obj
    elif isinstance(obj, dict):
        for v in obj.values():
            yield from _strings(v)
    elif isinstance(obj, (list, tuple)):
        for v in obj:
            yield from _strings(v)


def _source_constants(path: Path) -> list[str]:
    """The string constants of a Python file (empty when it does not parse)."""
    try:
        tree = ast.parse(path.read_text(), filename=str(path))
    except (OSError, SyntaxError, ValueError):
        return []
    return [n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)]


def _imported_names(path: Path, package: str | None) -> set[str]:
    """Every module a Python file's import statements name (at any depth), with their parent packages."""
    try:
        tree = ast.parse(path.read_text(), filename=str(path))
    except (OSError, SyntaxError, ValueError):
        return set()
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                try:
                    base = importlib.util.resolve_name("." * node.level + base, package)
                except (ImportError, ValueError):
                    continue
            names.add(base)
            names.update(f"{base}.{alias.name}" for alias in node.names)  # `from pkg import submodule`
    return {".".join(n.split(".")[:i]) for n in names if n for i in range(1, n.count(".") + 2)}


def _module_file(module: Any, libraries: tuple[str, ...] = ()) -> Path | None:
    """A module's source file where it counts as a scene input (not the installation's or a library's,
    not gevsim's)."""
    file = getattr(module, "__file__", None)
    if isinstance(file, str) and file.endswith(".py") and _is_input(os.path.realpath(file), libraries):
        return Path(file).resolve()
    return None


def _helper_modules(builder: Path, module: Any) -> set[Path]:
    """The helper modules a builder imports, directly or through each other: the import statements'
    names looked up in ``sys.modules``. Unlike the modules a build adds to ``sys.modules``, this is
    the same in a process's second build (``from helper import X`` binds no module; issue 24 #7)."""
    found: set[Path] = set()
    libraries = _library_roots(builder.parent)
    todo, seen = [(builder, getattr(module, "__package__", None))], set[str]()
    while todo:
        path, package = todo.pop()
        for name in sorted(_imported_names(path, package) - seen):
            seen.add(name)
            mod = sys.modules.get(name)
            file = _module_file(mod, libraries)
            if file is not None and file not in found:
                found.add(file)
                todo.append((file, getattr(mod, "__package__", None)))
    return found


def _import_builder(path: Path) -> Any:
    spec = importlib.util.spec_from_file_location(f"gevsim_scene_{path.stem}", path)
    if spec is None or spec.loader is None:
        raise ConfigError("not an importable Python file", source=str(path))
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except Exception as exc:
        raise ConfigError(f"scene builder failed to import: {exc}", source=str(path)) from exc
    if not callable(getattr(module, "build", None)):
        raise ConfigError("scene builder defines no build(options) function", source=str(path))
    return module


def load_builder(path: Path) -> Callable[[dict], dict]:
    """Import a scene builder file and return its ``build`` function."""
    return _import_builder(Path(path)).build


def _signature(path: Path) -> tuple:
    try:
        st = path.stat()
    except OSError:
        return (str(path), None)
    return (str(path), st.st_ino, st.st_size, st.st_mtime_ns)


def _memo_key(manifest: SceneManifest) -> tuple[str, str]:
    return (str(Path(manifest.builder).resolve()), json.dumps(manifest.options, sort_keys=True, default=str))


def build_shapes(manifest: SceneManifest) -> tuple[dict, tuple[Path, ...]]:
    """Import the manifest's builder and call ``build(options)`` (Mitsuba's variant must be set).

    Returns the shapes dict and the files the builder is made of and loads
    (the builder first, then the rest sorted; see the module docstring).
    """
    builder = Path(manifest.builder).resolve()
    if is_xml(builder):  # a Mitsuba XML scene: its objects, and the files its XML names
        import mitsuba as mi

        files = tuple(xml_inputs(builder, manifest.options))  # first: it refuses a FIFO Mitsuba would block on
        return load_xml_objects(mi, builder, dict(manifest.options)), files
    before = set(sys.modules)
    with _recording() as opened:
        module = _import_builder(builder)
        shapes = call_build(module.build, manifest, builder)
    if not isinstance(shapes, dict):
        raise ConfigError("build(options) must return a dict of Mitsuba objects", source=str(builder))
    libraries = _library_roots(builder.parent)
    found = {Path(p).resolve() for p in map(os.fsdecode, opened) if _is_input(os.path.realpath(p), libraries)}
    modules = [sys.modules[m] for m in set(sys.modules) - before if m in sys.modules]
    modules += [v for v in vars(module).values() if type(v) is type(sys)]
    found.update(f for f in (_module_file(m, libraries) for m in modules) if f is not None)
    found |= _helper_modules(builder, module)
    found |= _named_files(_strings(shapes), (builder.parent, Path.cwd()))
    found |= _named_files(_source_constants(builder), (builder.parent,))
    found |= _named_files(_strings(manifest.options), {builder.parent, Path(manifest.source).resolve().parent})
    found.discard(builder)
    key = _memo_key(manifest)
    with _memo_lock:  # what an earlier build in this process found stays listed: a module imported, or a file
        found |= _ever_found.setdefault(key, set())  # a helper reads on import, only once per process (#7)
        _ever_found[key] = set(found)
        files = (builder, *sorted(found))
        _found[key] = (tuple(_signature(f) for f in files), files)
    return shapes, files


def builder_files(manifest: SceneManifest) -> tuple[Path, ...]:
    """The builder and the files it loads (:func:`build_shapes`), without building a Mitsuba scene.

    Remembered per process while none of those files changes; otherwise the
    builder is run again (it needs Mitsuba: the variant of the manifest's flavour
    is activated).
    """
    if is_xml(manifest.builder):
        return tuple(xml_inputs(manifest.builder, manifest.options))
    with _memo_lock:
        known = _found.get(_memo_key(manifest))
    if known is not None and all(_signature(Path(s[0])) == s for s in known[0]):
        return known[1]
    from gevsim.render import backend

    backend.activate(manifest.render.flavour)
    return build_shapes(manifest)[1]


def scene_input_files(manifest: SceneManifest) -> tuple[Path, ...]:
    """Every file a scene is made of: its manifests (``extends`` chain), builder and what the builder loads."""
    return tuple(dict.fromkeys((*manifest.manifests, *builder_files(manifest))))


def file_sha256(path: Path) -> str:
    """SHA-256 of a file's contents (remembered while its inode, size and mtime stay the same)."""
    sig = _signature(Path(path))
    if sig[1] is None:
        return "missing"
    with _memo_lock:
        known = _hashes.get(sig)
    if known is not None:
        return known
    try:
        digest = sha256_of(path, source=str(path))  # a FIFO, device or huge file: ConfigError, never a hang
    except OSError:
        return "unreadable"
    with _memo_lock:
        _hashes[sig] = digest
    return digest


def files_digest(files: Iterable[Path], *, base: Path) -> str:
    """SHA-256 over the files' names (relative to ``base`` where inside it) and contents."""
    base = Path(base).resolve()
    h = hashlib.sha256()
    for f in sorted({Path(f).resolve() for f in files}):
        name = str(f.relative_to(base)) if f.is_relative_to(base) else str(f)
        h.update(f"{name}\0{file_sha256(f)}\n".encode())
    return h.hexdigest()


def scene_digest(scene: str | os.PathLike | SceneManifest) -> str:
    """Content hash of every file a scene is made of (:func:`scene_input_files`): a scene name, manifest
    path or loaded manifest."""
    if not isinstance(scene, SceneManifest):
        from gevsim.render.manifest import load

        scene = load(scene if isinstance(scene, str) else Path(scene))
    return files_digest(scene_input_files(scene), base=Path(scene.builder).parent)
