"""Outputs gevsim owns (issues 24 and 36): gevsim replaces or writes into only a folder or file it
wrote itself, of the same kind, and never an input of the same run.

A folder output carries a mark, :data:`~gevsim.io.mark.MARK` (``.gevsim.output``), recording its
``kind`` and every file (size and SHA-256) and folder gevsim wrote there (:mod:`gevsim.io.mark`). A
folder may receive an output of kind K when it is missing or empty, or when it carries the mark of kind
K and its contents are what the mark records: exactly, for a folder replaced whole (render,
reconstruction, validation); for a folder written into (study, dataset), every file there recorded and
unchanged, but for the work in progress of a run that was killed (:func:`gevsim.io.mark.difference`).
A folder without a mark is never taken for gevsim's, whatever its layout or its ``manifest.json``
says; a mark that does not match its files is refused. Each refusal is one
:class:`~gevsim.errors.ConfigError` naming the folder and its first foreign, changed or missing entry.
The lock file and leftover stages (:mod:`gevsim.io.staging`) are gevsim's by name: a folder holding
only those counts as empty.

A file output (an emulation file, an AEDAT4 export) may replace only a file of its own kind; a
kind's test lives with its format (``is_ours``). Names from configs that become path parts (light
groups, methods, sensor names in a report) must pass :func:`check_name`.
"""

from __future__ import annotations

import os
import re
import stat
from collections.abc import Callable, Iterable
from pathlib import Path

from gevsim.errors import ConfigError
from gevsim.io.mark import (  # noqa: F401 (re-exported: they lived here)
    FOLDER_KINDS,
    MARK,
    REPLACED_KINDS,
    RESUMED_KINDS,
    difference,
    read_mark,
    write_mark,
)
from gevsim.io.staging import _STAGE, LOCK_NAME, sweep_stale

#: A name that becomes one path part: letters, digits, ``_``, ``.``, ``-``; no leading ``.`` or ``-``.
NAME_MAX = 64
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")


def check_name(name: object, *, source: str | None = None, key: str | None = None) -> str:
    """Return ``name`` if it is safe as one path part (:data:`NAME_MAX` characters of ``A-Z a-z 0-9 _ . -``,
    not starting with ``.`` or ``-``: no separator, no ``..``, not absolute); else raise ConfigError."""
    if not isinstance(name, str) or len(name) > NAME_MAX or not _NAME.fullmatch(name):
        raise ConfigError(f"{name!r} is not a safe name: use up to {NAME_MAX} letters, digits, '_', '.' or '-', "
                          "not starting with '.' or '-'", source=source, key=key)
    return name


def _entries(folder: Path) -> set[str]:
    """Top-level names of ``folder`` but what is gevsim's by name: the lock file (a plain file, not a
    link or a folder) and leftover stages."""
    names = set()
    for entry in os.scandir(folder):
        if entry.name == LOCK_NAME and entry.is_file(follow_symlinks=False) or _STAGE.match(entry.name):
            continue
        names.add(entry.name)
    return names


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
        mark = read_mark(folder)
        if mark is None:
            if names:
                raise ConfigError(f"holds files gevsim did not write ({_listing(names)}) and no gevsim mark ({MARK}): "
                                  "gevsim replaces or writes into only folders it marked as its own; remove it or "
                                  "choose another output folder", source=src)
            return
        if mark["kind"] != kind:
            raise ConfigError(f"holds a gevsim {mark['kind']} output, not a {kind} output; choose another output "
                              "folder", source=src)
        why = difference(folder, mark, kind)
    except OSError as exc:
        raise ConfigError(f"cannot read this folder ({exc.strerror or exc})", source=src) from None
    if why is not None:
        raise ConfigError(why, source=src)


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
