"""The mark of a folder gevsim wrote (issue 36, item 1): ``.gevsim.output``, a JSON record of every file
and folder gevsim wrote there, so that ownership is decided by content, not by names or layout.

The mark holds ``kind`` (one of :data:`FOLDER_KINDS`), the ``gevsim`` version, ``folders`` (every
sub-folder, as a relative POSIX path) and ``files`` (every regular file, recursively: relative path ->
``[size in bytes, sha256 hex digest]``). Nothing else is gevsim's: a symbolic link, a FIFO or a device
anywhere in the tree is never recorded, so it is always foreign.

Why the SHA-256 of the contents, not size + ``mtime_ns`` + inode: the question the mark answers is
"are these bytes still the ones gevsim wrote?", and only the contents answer it. Metadata both misses
and invents changes: an edit restored with ``touch -r`` or a tool that keeps mtimes keeps size and
mtime; a copy (``cp -a``, ``shutil.copytree``, a backup restored) changes every inode, so a copied
render or dataset would no longer be gevsim's; on file systems with coarse timestamps an edit in the
same second goes unseen. The cost is one read of each file: SHA-256 runs at ~800 MB/s on one core of
the 2-core CI VM (``hashlib``), so a 1 GB render costs ~1.3 s per check, small beside the render that
wrote it, and the files gevsim just wrote are read back from the page cache. Files are hashed only
where the record names them with the same size, so a foreign file is refused on its name or size,
never read whole.

Folders replaced whole (:data:`REPLACED_KINDS`: render, reconstruction, validation) are written in a
stage and marked there before the swap: their tree must be exactly the record, nothing added, changed,
replaced by a link or a folder, or missing (a renamed file is one missing and one foreign).

Folders written into (:data:`RESUMED_KINDS`: study, dataset) are recorded whole when a run ends well
(:func:`write_mark`, under the folder's lock). The next run writes only into a folder whose files are
all recorded and unchanged, so a note, an edited ``report.md``, a figure or a file put into a run's work
folder (which gevsim would overwrite or delete) is refused, not lost. A file gevsim wrote may be missing
(a user deleting a repeat's marker to redo it loses nothing). While a run writes, the mark is ``open``
(:func:`open_mark`): a run that was killed or failed leaves it so, and its work in progress is in the
kind's :data:`CLAIMS` (a study's ``runs/`` and ``render-cache/``, a dataset's ``shards/`` and
``evreal/``, all named and managed by gevsim, which the rerun resumes), so under an open mark anything
under a claim is accepted as the dead run's, and everything else must still match the record. Files
written into the folder while a run is writing are taken for the run's. Stages
(``.NAME.gevsim-XXXXXXXX...``, :mod:`gevsim.io.staging`), the lock file and the mark are gevsim's by
name in a resumed folder.

Limits: a file put inside a replaced folder between its last check and the swap (the time the check
takes) is not seen; after a killed study or dataset run, a file put under a claim before the rerun is
taken for the dead run's; a ``--cache`` inside a study folder under another name than ``render-cache``
is not a claim, so after a failed run its new entries are refused (one line) rather than resumed. A mark
is read up to :data:`MARK_MAX_BYTES`; a mark that records no files (an earlier gevsim's, or hand-written)
makes its folder no one's.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import re
import stat
from collections.abc import Callable, Iterator
from pathlib import Path

import gevsim
from gevsim.io.staging import _STAGE, LOCK_NAME, atomic_write_text

#: The mark of a folder gevsim wrote (JSON: kind, gevsim version, folders, files).
MARK = ".gevsim.output"
#: Folder outputs replaced whole (their tree must be exactly the record) and those written into, resumably.
REPLACED_KINDS = ("render", "reconstruction", "validation")
RESUMED_KINDS = ("study", "dataset")
FOLDER_KINDS = REPLACED_KINDS + RESUMED_KINDS
#: What a resumed kind's run writes while its mark is open: top-level folders that gevsim names and resumes.
CLAIMS = {"study": ("runs", "render-cache"), "dataset": ("shards", "evreal")}
#: A mark larger than this is not one gevsim wrote (about two million files).
MARK_MAX_BYTES = 1 << 28
_SHA256 = re.compile(r"[0-9a-f]{64}")
_CHUNK = 1 << 20


def read_mark(folder: str | os.PathLike) -> dict | None:
    """The mark of ``folder`` (a dict with a string ``kind``), or None where it has none or a bad one.
    The mark is never followed through a link, and a FIFO or device in its place is not opened for reading."""
    path = Path(folder) / MARK
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return None
    with os.fdopen(fd, "rb") as fh:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        data = fh.read(MARK_MAX_BYTES + 1)
    with contextlib.suppress(ValueError):
        mark = json.loads(data) if len(data) <= MARK_MAX_BYTES else None
        if isinstance(mark, dict) and isinstance(mark.get("kind"), str):
            return mark
    return None


def digest(path: str | os.PathLike) -> str | None:
    """The SHA-256 of a regular file's contents, or None where it is not one (a link is never followed, a
    FIFO or device never read); OSError where it cannot be read."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError as exc:
        if exc.errno == errno.ELOOP:  # it became a link
            return None
        raise
    with os.fdopen(fd, "rb") as fh:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        sha = hashlib.sha256()
        while chunk := fh.read(_CHUNK):
            sha.update(chunk)
    return sha.hexdigest()


def _scan(root: Path, skip: Callable[[str], bool]) -> Iterator[tuple[str, os.stat_result]]:
    """(relative POSIX path, lstat) of every entry under ``root``, sorted, each folder before its contents
    (read only when the caller asks for them); an entry that ``skip`` names is left out with everything under
    it. Links are entries, never followed."""
    stack: list[tuple[str, Iterator[tuple[str, os.DirEntry]]]] = [("", _sorted(root))]
    while stack:
        rel, entries = stack[-1]
        item = next(entries, None)
        if item is None:
            stack.pop()
            continue
        path = f"{rel}/{item[0]}" if rel else item[0]
        if skip(path):
            continue
        st = item[1].stat(follow_symlinks=False)
        yield path, st
        if stat.S_ISDIR(st.st_mode):
            stack.append((path, _sorted(root / path)))


def _sorted(folder: Path) -> Iterator[tuple[str, os.DirEntry]]:
    with os.scandir(folder) as entries:
        return iter(sorted((entry.name, entry) for entry in entries))


def _skipper(kind: str) -> Callable[[str], bool]:
    """What a kind's record leaves out: the mark; for a resumed kind also the lock file and stages."""
    if kind in REPLACED_KINDS:
        return lambda path: path == MARK
    return lambda path: path in (MARK, LOCK_NAME) or bool(_STAGE.match(path.rpartition("/")[2]))


def record(folder: str | os.PathLike, kind: str) -> dict:
    """The mark of ``folder`` as it is now: every folder and regular file (size and SHA-256) under it."""
    root = Path(folder)
    folders, files = [], {}
    for path, st in _scan(root, _skipper(kind)):
        if stat.S_ISDIR(st.st_mode):
            folders.append(path)
        elif stat.S_ISREG(st.st_mode):
            files[path] = [st.st_size, digest(root / path)]
    return {"kind": kind, "gevsim": gevsim.__version__, "folders": folders, "files": files}


def write_mark(folder: str | os.PathLike, kind: str) -> None:
    """Mark ``folder`` as a gevsim output of ``kind``, recording every file and folder it holds now."""
    if kind not in FOLDER_KINDS:
        raise ValueError(f"kind must be one of {', '.join(FOLDER_KINDS)}, got {kind!r}")
    _write(folder, record(folder, kind))


def open_mark(folder: str | os.PathLike, kind: str) -> None:
    """A resumed kind's run starts writing into ``folder`` (its lock held): the mark keeps its last record
    and says ``open`` until :func:`write_mark` records the folder at the run's end."""
    if kind not in RESUMED_KINDS:
        raise ValueError(f"kind must be one of {', '.join(RESUMED_KINDS)}, got {kind!r}")
    folders, files = _records(read_mark(folder) or {})
    _write(folder, {"kind": kind, "gevsim": gevsim.__version__, "folders": sorted(folders), "files": files or {},
                    "open": True})


def _write(folder: str | os.PathLike, mark: dict) -> None:
    atomic_write_text(Path(folder) / MARK, json.dumps(mark, separators=(",", ":")) + "\n")


def _records(mark: dict) -> tuple[set[str], dict | None]:
    """The mark's recorded folders and files; files None where the record is missing or not gevsim's."""
    folders, files = mark.get("folders"), mark.get("files")
    if not isinstance(folders, list) or not all(isinstance(f, str) for f in folders) or not isinstance(files, dict):
        return set(), None
    for value in files.values():
        if not (isinstance(value, list) and len(value) == 2 and type(value[0]) is int and value[0] >= 0
                and isinstance(value[1], str) and _SHA256.fullmatch(value[1])):
            return set(), None
    return set(folders), files


_WHAT = {stat.S_IFLNK: "a symbolic link", stat.S_IFDIR: "a folder", stat.S_IFREG: "a file"}


def _what(st: os.stat_result) -> str:
    return _WHAT.get(stat.S_IFMT(st.st_mode), "a special file")


def difference(folder: str | os.PathLike, mark: dict, kind: str) -> str | None:
    """Why ``folder`` may not receive a ``kind`` output although its ``mark`` is of that kind: its first
    foreign, changed or missing entry (in sorted order) and what to do, in one sentence; None where it holds
    what the mark records (see the module's notes for what each kind may differ in)."""
    folders, files = _records(mark)
    if files is None:
        first = next(_scan(Path(folder), _skipper(kind)), None)
        if first is None:
            return None
        return (f"its mark ({MARK}) records no files (a mark of an earlier gevsim, or not gevsim's), so nothing "
                f"here (first: {first[0]}) can be told from yours: choose another output folder, or remove this one if "
                "nothing in it is yours")
    problem = _first_difference(Path(folder), kind, folders, files, is_open=mark.get("open") is True)
    if problem is None:
        return None
    verb = "replaces" if kind in REPLACED_KINDS else "writes into"
    advice = "restore it, remove the folder yourself" if problem.endswith("(moved or deleted)") else "move it out"
    return (f"{problem}; gevsim {verb} a {kind} folder only while it holds what gevsim wrote there: {advice} or "
            "choose another output folder")


def _first_difference(root: Path, kind: str, folders: set[str], files: dict, *, is_open: bool) -> str | None:
    claims = CLAIMS.get(kind, ()) if is_open else ()
    seen = set()
    for path, st in _scan(root, _skipper(kind)):
        if path.partition("/")[0] in claims and (path not in claims or stat.S_ISDIR(st.st_mode)):
            continue  # a dead run's work in progress (a claim itself must be a folder, not a link)
        seen.add(path)
        if stat.S_ISDIR(st.st_mode) and path in folders:
            continue
        recorded = files.get(path)
        if recorded is None:
            return f"{path} is {_what(st)} gevsim did not write" if path not in folders else \
                f"{path} was a folder gevsim wrote and is now {_what(st)}"
        if not stat.S_ISREG(st.st_mode):
            return f"{path} was a file gevsim wrote and is now {_what(st)}"
        if st.st_size != recorded[0] or digest(root / path) != recorded[1]:
            return f"{path} was changed since gevsim wrote it"
    if kind in REPLACED_KINDS:
        for path in sorted(folders.union(files) - seen):
            return f"{path}, which gevsim wrote, is missing (moved or deleted)"
    return None
