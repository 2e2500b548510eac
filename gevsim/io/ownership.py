"""Outputs gevsim owns (issue 24): gevsim replaces or writes into only a folder or file it wrote itself,
of the same kind, and never an input of the same run.

A folder output carries a small JSON mark, :data:`MARK` (``.gevsim.output``), naming its ``kind``
(one of :data:`FOLDER_KINDS`), the gevsim version and, for the folders that are replaced whole
(render, reconstruction, validation), the top-level ``entries`` gevsim wrote there. A folder may
receive an output of kind K when it is missing or empty, or when it carries the mark of kind K and
(for a replaced folder) holds nothing beyond the entries the mark lists. A folder written before the
mark existed is recognised by its layout (:func:`legacy_kind`), so earlier outputs can be replaced
or resumed. Anything else is refused with one :class:`~gevsim.errors.ConfigError`. The lock file
and leftover stages (:mod:`gevsim.io.staging`) are gevsim's by name and never count as foreign.

A file output (an emulation file, an AEDAT4 export) may replace only a file of its own kind; a
kind's test lives with its format (``is_ours``). Names from configs that become path parts (light
groups, methods, sensor names in a report) must pass :func:`check_name`.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import stat
from collections.abc import Callable, Iterable
from pathlib import Path

import gevsim
from gevsim.errors import ConfigError
from gevsim.io.staging import _STAGE, LOCK_NAME, MANIFEST, atomic_write_text, sweep_stale

#: The mark of a folder gevsim wrote (JSON: kind, gevsim version, entries).
MARK = ".gevsim.output"
#: Folder outputs replaced whole (their mark lists what they hold) and those written into, resumably.
REPLACED_KINDS = ("render", "reconstruction", "validation")
RESUMED_KINDS = ("study", "dataset")
FOLDER_KINDS = REPLACED_KINDS + RESUMED_KINDS
#: A name that becomes one path part: letters, digits, ``_``, ``.``, ``-``; no leading ``.`` or ``-``.
NAME_MAX = 64
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")
_MARK_MAX_BYTES = 1 << 16

# What each kind wrote before the mark existed (top-level names, and the manifest keys it always has).
_RUN_ID = re.compile(r"[0-9a-f]{16}")  # a study's runs/<id>
_SHARD = re.compile(r"seq_[0-9]{5,}\.(json|h5)")  # a dataset's shards/seq_NNNNN.*
# Top-level names of a study (runs, its cache, results, report, plots) and of a dataset folder.
_LEGACY_STUDY = re.compile(r"runs|render-cache|config\.toml|report\.md|results\.(csv|json)|maps\.npz|[a-z0-9_]+\.png")
_LEGACY_DATASET = re.compile(r"shards|evreal|dataset\.json|render-cache")
_LEGACY_FILES = {
    "render": ({"basis", "frames", MANIFEST, "contact_sheet.png", "waveform.png"},
               {"gevsim", "scene", "light_groups", "poses"}),
    "reconstruction": ({"frames", MANIFEST, "metrics.csv", "metrics.json", "side_by_side.png"},
                       {"gevsim", "source", "methods", "tone_map"}),
}


def check_name(name: object, *, source: str | None = None, key: str | None = None) -> str:
    """Return ``name`` if it is safe as one path part (:data:`NAME_MAX` characters of ``A-Z a-z 0-9 _ . -``,
    not starting with ``.`` or ``-``: no separator, no ``..``, not absolute); else raise ConfigError."""
    if not isinstance(name, str) or len(name) > NAME_MAX or not _NAME.fullmatch(name):
        raise ConfigError(f"{name!r} is not a safe name: use up to {NAME_MAX} letters, digits, '_', '.' or '-', "
                          "not starting with '.' or '-'", source=source, key=key)
    return name


def read_mark(folder: str | os.PathLike) -> dict | None:
    """The mark of ``folder`` (a dict with a string ``kind``), or None where it has none or a bad one."""
    path = Path(folder) / MARK
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return None
    with os.fdopen(fd, "rb") as fh:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        data = fh.read(_MARK_MAX_BYTES + 1)
    with contextlib.suppress(ValueError):
        mark = json.loads(data) if len(data) <= _MARK_MAX_BYTES else None
        if isinstance(mark, dict) and isinstance(mark.get("kind"), str):
            return mark
    return None


def write_mark(folder: str | os.PathLike, kind: str) -> None:
    """Mark ``folder`` as a gevsim output of ``kind``; a replaced kind's mark lists the folder's entries."""
    if kind not in FOLDER_KINDS:
        raise ValueError(f"kind must be one of {', '.join(FOLDER_KINDS)}, got {kind!r}")
    mark: dict = {"kind": kind, "gevsim": gevsim.__version__}
    if kind in REPLACED_KINDS:
        mark["entries"] = sorted(_entries(folder))
    atomic_write_text(Path(folder) / MARK, json.dumps(mark, indent=1) + "\n")


def _entries(folder: str | os.PathLike) -> set[str]:
    """Top-level names of ``folder`` except the mark, the lock file and leftover stages."""
    return {n for n in os.listdir(folder) if n not in (MARK, LOCK_NAME) and not _STAGE.match(n)}


def legacy_kind(folder: str | os.PathLike, names: Iterable[str] | None = None) -> str | None:
    """The kind of an unmarked folder that an earlier gevsim wrote, judged by its layout; None if none fits.

    render, reconstruction: only the names that kind writes, and a ``manifest.json`` with its keys;
    validation: ``report.md`` and sensor folders that each hold ``results.json``; study: a ``runs``
    folder of run ids; dataset: a ``shards`` folder of ``seq_NNNNN`` files or a ``dataset.json`` with
    its keys (neither with a ``manifest.json``).
    """
    folder = Path(folder)
    names = set(_entries(folder) if names is None else names)
    for kind, (allowed, keys) in _LEGACY_FILES.items():
        if MANIFEST in names and names <= allowed:
            manifest = _small_json(folder / MANIFEST)
            if isinstance(manifest, dict) and keys <= manifest.keys():
                return kind
    if MANIFEST in names:
        return None
    sensors = names - {"report.md"}
    if "report.md" in names and sensors and all((folder / n / "results.json").is_file() for n in sensors):
        return "validation"
    if all(_LEGACY_STUDY.fullmatch(n) for n in names) and _only(folder / "runs", _RUN_ID):
        return "study"
    record = _small_json(folder / "dataset.json")
    if all(_LEGACY_DATASET.fullmatch(n) for n in names) and (_only(folder / "shards", _SHARD) or (
            isinstance(record, dict) and {"gevsim_version", "sequences"} <= record.keys())):
        return "dataset"
    return None


def _only(folder: Path, pattern: re.Pattern) -> bool:
    """Whether ``folder`` is a folder (not a link) holding at least one entry that matches ``pattern``, and
    nothing else but stages."""
    try:
        entries = [] if folder.is_symlink() else os.listdir(folder)
    except OSError:
        return False
    return any(pattern.fullmatch(n) for n in entries) and all(pattern.fullmatch(n) or _STAGE.match(n)
                                                               for n in entries)


def _small_json(path: Path) -> object:
    try:
        if not path.is_file() or path.stat().st_size > 1 << 26:
            return None
        return json.loads(path.read_bytes())
    except (OSError, ValueError):
        return None


def _listing(names: Iterable[str], limit: int = 3) -> str:
    names = sorted(names)
    return ", ".join(names[:limit]) + (f" and {len(names) - limit} more" if len(names) > limit else "")


def check_folder(folder: str | os.PathLike, kind: str, *, inputs: Iterable[str | os.PathLike | None] = ()) -> None:
    """Raise ConfigError unless ``folder`` may receive an output of ``kind`` (see the module's notes), and
    unless every existing file of ``inputs`` lies outside it."""
    if kind not in FOLDER_KINDS:
        raise ValueError(f"kind must be one of {', '.join(FOLDER_KINDS)}, got {kind!r}")
    folder = Path(folder)
    src = str(folder)
    check_inputs_outside(folder, inputs)
    if not os.path.lexists(folder):
        return
    if not folder.is_dir():
        raise ConfigError("exists and is not a folder; choose another output folder", source=src)
    try:
        names = _entries(folder)
    except OSError as exc:
        raise ConfigError(f"cannot read this folder ({exc.strerror or exc})", source=src) from None
    mark = read_mark(folder)
    if mark is None:
        if not names:
            return
        found = legacy_kind(folder, names)
        if found is None:
            raise ConfigError(f"holds files gevsim did not write ({_listing(names)}); choose another output "
                              "folder", source=src)
    else:
        found = mark["kind"]
    if found != kind:
        raise ConfigError(f"holds a gevsim {found} output, not a {kind} output; choose another output folder",
                          source=src)
    if mark is not None and kind in REPLACED_KINDS:
        entries = mark.get("entries")
        extra = names - set(entries if isinstance(entries, list) else [])
        if extra:
            raise ConfigError(f"holds files gevsim did not write ({_listing(extra)}) beside its {kind} output; "
                              "choose another output folder", source=src)


def check_inputs_outside(out: Path, inputs: Iterable[str | os.PathLike | None]) -> None:
    """Refuse an output that is one of the run's inputs or, as a folder, holds one."""
    target = Path(os.path.realpath(out))
    for item in inputs:
        if item is None or not os.path.exists(item):
            continue
        path = Path(os.path.realpath(item))
        if path == target or target in path.parents:
            what = "is" if path == target else "holds"
            raise ConfigError(f"{what} an input of this run ({item}); choose another output", source=str(out))


def check_file(path: str | os.PathLike, kind: str, is_ours: Callable[[Path], bool], *,
               inputs: Iterable[str | os.PathLike | None] = ()) -> None:
    """Raise ConfigError unless the file output ``path`` of ``kind`` may be written: it is no input of the run
    and, where it exists, a regular file that ``is_ours`` recognises as a gevsim file of that kind."""
    path = Path(path)
    check_inputs_outside(path, inputs)
    if not os.path.lexists(path):
        return
    if path.is_dir():
        raise ConfigError("is a folder; name a file", source=str(path))
    try:
        regular = stat.S_ISREG(path.stat().st_mode)
    except OSError:  # a dangling link: replacing it loses nothing
        return
    if not regular or not is_ours(path):
        raise ConfigError(f"exists and is not a gevsim {kind} file; choose another output", source=str(path))


def sweep_beside(target: str | os.PathLike) -> None:
    """Remove the leftovers of killed runs (stages nobody holds) beside ``target``, whatever their target
    was: a killed run into one name leaves nothing behind once another output is written next to it."""
    sweep_stale(Path(target).parent, recursive=False)


def is_event_file(path: Path) -> bool:
    """Whether ``path`` is a gevsim event file (HDF5 with gevsim's ``format`` attribute): the kind an
    emulation may replace."""
    import h5py

    from gevsim.io.event_reader import READABLE_FORMATS

    try:
        if not h5py.is_hdf5(path):
            return False
        with h5py.File(path, "r", locking=False) as f:
            return f.attrs.get("format") in READABLE_FORMATS
    except (OSError, ValueError):
        return False
