"""Array jobs without a scheduler (issue 37, item 6): ``--part I/N`` makes share ``I`` of ``N`` of a dataset's
sequences or a study's jobs, and a merge moves the finished work into the output folder.

Part ``I`` of ``N`` takes the work items ``k`` (a dataset's sequence index, a study's job in its fixed order)
with ``k % N == I`` and writes them into its own folder beside the output, ``OUT.parts/I-of-N/``: a study or
dataset folder of its own, with its own lock, mark and resume (:func:`gevsim.io.exclusive`), so parts never
share a folder and need no lock across the cluster while they compute. Items already finished in ``OUT``
are not made again. Why a folder per part and not the shared ``OUT`` (docs/cluster.md): ``OUT``'s mark
records the SHA-256 of every file in it (:mod:`gevsim.io.mark`), checked when a run takes its lock and
recorded again when it ends; parts that took ``OUT``'s lock for each of their records would hash the whole
dataset once per part, and the lock would have to be coherent across the cluster's nodes.

The merge (:func:`merge_parts`, run under ``OUT``'s lock) takes each part folder in turn under that part's
lock, moves each item it finished into ``OUT`` (its files renamed, the done-marker last: an interrupted
merge leaves at worst an unfinished item, made again), drops an item ``OUT`` already holds finished (the
same bytes: same seed), and removes a part folder left with nothing of its own. It runs when the last part
finishes (:func:`unfinished` is 0), with ``--merge``, and at the start of every run without ``--part``.
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import shutil
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from gevsim.errors import ConfigError, clipped
from gevsim.io import exclusive, sweep_stale
from gevsim.io.atomic import FolderBusy
from gevsim.io.mark import MARK, read_mark
from gevsim.io.staging import LOCK_NAME

log = logging.getLogger(__name__)

#: The most parts an output may be split into.
MAX_PARTS = 1_000_000
#: How long the merge by the last part waits for a part folder whose work is finished but whose process is
#: still recording it (its mark hashes every file: about a minute per 50 GB), and how often it looks.
MERGE_WAIT_S = 1800.0
POLL_S = 0.5
_TEXT = re.compile(r"\s*(\d{1,18})\s*/\s*(\d{1,18})\s*")
_FOLDER = re.compile(r"(\d{1,7})-of-(\d{1,7})")


@dataclass(frozen=True)
class Part:
    """Part ``index`` of ``count``: the work items ``k`` with ``k % count == index``."""

    index: int
    count: int

    @property
    def name(self) -> str:
        return f"{self.index}-of-{self.count}"

    def takes(self, k: int) -> bool:
        return k % self.count == self.index

    def __str__(self) -> str:
        return f"{self.index}/{self.count}"


def parse_part(text: str) -> Part:
    """``"I/N"`` (0 <= I < N, as ``$SLURM_ARRAY_TASK_ID/N`` of ``sbatch --array=0-<N-1>``) as a :class:`Part`;
    anything else is a ConfigError naming ``--part``."""
    found = _TEXT.fullmatch(str(text))
    if found is None:
        raise ConfigError(f"expected I/N, part I of N (0 <= I < N, as $SLURM_ARRAY_TASK_ID/N), got {clipped(text)!r}",
                          key="--part")
    index, count = int(found[1]), int(found[2])
    if not 1 <= count <= MAX_PARTS:
        raise ConfigError(f"N must be from 1 to {MAX_PARTS}, got {text!r}", key="--part")
    if index >= count:
        raise ConfigError(f"I must be below N (parts are numbered 0 to N-1, as sbatch --array=0-{count - 1}), got "
                          f"{text!r}", key="--part")
    return Part(index, count)


def parts_root(out: str | os.PathLike) -> Path:
    """The folder of an output's part folders: ``OUT.parts`` beside ``OUT``."""
    path = Path(os.path.abspath(out))
    if not path.name:
        raise ConfigError("has no name to put its parts beside (OUT.parts); choose another output folder",
                          source=str(out))
    return path.with_name(path.name + ".parts")


def part_folder(out: str | os.PathLike, part: Part) -> Path:
    """Where part ``part`` of the output ``out`` writes: ``OUT.parts/I-of-N``."""
    return parts_root(out) / part.name


def part_folders(out: str | os.PathLike, kind: str) -> list[tuple[Path, Part]]:
    """The part folders of ``out`` that carry a mark of ``kind`` (folders named ``I-of-N``, not links), by N
    then I; anything else in ``OUT.parts`` is not gevsim's and is left alone."""
    root = parts_root(out)
    try:
        entries = sorted(os.scandir(root), key=lambda e: e.name)
    except OSError:
        return []
    found = []
    for entry in entries:
        name = _FOLDER.fullmatch(entry.name)
        if name and entry.is_dir(follow_symlinks=False) and int(name[1]) < int(name[2]):
            mark = read_mark(entry.path)
            if mark is not None and mark["kind"] == kind:
                found.append((Path(entry.path), Part(int(name[1]), int(name[2]))))
    return sorted(found, key=lambda item: (item[1].count, item[1].index))


@dataclass(frozen=True)
class Work:
    """What a merge needs of a study or a dataset: its folder ``kind``, its ``count`` items, whether item
    ``k`` is finished in a folder, and item ``k``'s files and folders (relative paths, the done-marker last).
    ``scratch``: top-level folders a part may hold that are not items (a study's render cache): removed with
    the emptied part folder."""

    kind: str
    count: int
    finished: Callable[[Path, int], bool]
    files: Callable[[int], tuple[str, ...]]
    scratch: tuple[str, ...] = ()


def owned(out: str | os.PathLike, kind: str) -> bool:
    """Whether ``out`` carries a mark of ``kind``: only then are its done-markers read without its lock."""
    mark = read_mark(out) if Path(out).is_dir() else None
    return mark is not None and mark["kind"] == kind


def check_out(out: str | os.PathLike, kind: str) -> None:
    """Refuse, before a part computes anything, an output folder its merge could not write into: one that is
    neither missing, empty nor marked ``kind`` (:func:`gevsim.io.ownership.check_folder`). A marked one is
    checked whole by the merge, under its lock: not by every part."""
    from gevsim.io.ownership import check_folder

    if not owned(out, kind):
        check_folder(out, kind)


def unfinished(out: str | os.PathLike, work: Work) -> int:
    """How many items are finished neither in ``out`` (when it is ``work.kind``'s) nor in the part folder that
    takes them (read without locks: markers are written atomically, and the merge checks again under them)."""
    folders = part_folders(out, work.kind)
    in_out = owned(out, work.kind)
    return sum(not ((in_out and work.finished(Path(out), k))
                    or any(part.takes(k) and work.finished(folder, k) for folder, part in folders))
               for k in range(work.count))


@contextlib.contextmanager
def _hold(folder: Path, kind: str, wait_s: float) -> Iterator[None]:
    """``folder``'s lock (:func:`gevsim.io.exclusive`), waiting up to ``wait_s`` while another process holds it."""
    deadline, said = time.monotonic() + wait_s, 0.0
    while True:
        stack = contextlib.ExitStack()
        try:
            stack.enter_context(exclusive(folder, what=kind, kind=kind))
            break
        except FolderBusy:
            now = time.monotonic()
            if now >= deadline:
                raise
            if now - said >= 30.0:
                log.warning("waiting for the process writing %s to finish", folder)
                said = now
            time.sleep(POLL_S)
    with stack:
        yield


def _remove(root: Path, names: tuple[str, ...]) -> None:
    """Remove an item's files and folders under ``root``, its done-marker first."""
    for name in reversed(names):
        path = root / name
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        elif os.path.lexists(path):
            path.unlink()


def _move(src: Path, dst: Path, names: tuple[str, ...]) -> None:
    """Move an item's files and folders from ``src`` to ``dst`` (renamed; copied across file systems), its
    done-marker last: until the marker is in, the item is not finished in ``dst``."""
    for name in names:
        if os.path.lexists(src / name):
            (dst / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.move(src / name, dst / name)


def _take(folder: Path, part: Part, out: Path, work: Work) -> tuple[int, int]:
    """Move the items ``folder`` finished into ``out`` (both locked); returns (moved, already in ``out``)."""
    moved = dropped = 0
    for k in range(part.index, work.count, part.count):
        if not work.finished(folder, k):
            continue
        names = work.files(k)
        if work.finished(out, k):
            _remove(folder, names)
            dropped += 1
            continue
        _remove(out, names)  # a stale or unfinished earlier one (out is gevsim's: checked under its lock)
        _move(folder, out, names)
        moved += 1
    return moved, dropped


def _empty(folder: Path, scratch: tuple[str, ...]) -> bool:
    """Whether ``folder`` holds nothing but folders, scratch, its mark and its lock."""
    for top in os.scandir(folder):
        if top.name in (MARK, LOCK_NAME) or top.name in scratch and top.is_dir(follow_symlinks=False):
            continue
        if not top.is_dir(follow_symlinks=False):
            return False
        for _, _, files in os.walk(top.path):
            if files:
                return False
    return True


def _drop(folder: Path, scratch: tuple[str, ...]) -> None:
    """Remove an emptied part folder (called under its lock); its mark and lock go last, after the lock is
    released, by :func:`_drop_shell`."""
    for name in scratch:
        if (folder / name).is_dir() and not (folder / name).is_symlink():
            shutil.rmtree(folder / name)
    for top in os.scandir(folder):
        if top.is_dir(follow_symlinks=False):
            for dirpath, _, _ in sorted(os.walk(top.path), key=lambda w: -len(w[0])):
                with contextlib.suppress(OSError):  # not empty after all: kept, and the part folder with it
                    os.rmdir(dirpath)


def _drop_shell(folder: Path) -> None:
    with contextlib.suppress(OSError):  # a file put there meanwhile keeps the folder
        (folder / MARK).unlink()
        (folder / LOCK_NAME).unlink()
        folder.rmdir()


def merge_parts(out: str | os.PathLike, work: Work, *, wait_s: float = 0.0) -> dict:
    """Move what the part folders of ``out`` finished into ``out`` (the caller holds ``out``'s lock; see the
    module's notes). A part folder another process holds is waited for up to ``wait_s``, then left for a
    later merge. Returns ``moved`` and ``dropped`` (items), ``parts`` (folders emptied and removed) and
    ``busy`` (folders left because another process held them)."""
    out = Path(out)
    moved = dropped = removed = 0
    busy = []
    for folder, part in part_folders(out, work.kind):
        try:
            with _hold(folder, work.kind, wait_s):
                sweep_stale(folder)
                m, d = _take(folder, part, out, work)
                moved, dropped = moved + m, dropped + d
                empty = _empty(folder, work.scratch)
                if empty:
                    _drop(folder, work.scratch)
        except FolderBusy:
            busy.append(str(folder))
            continue
        if empty:
            _drop_shell(folder)
            removed += 1
    with contextlib.suppress(OSError):  # only when empty: anything else in it is not gevsim's
        parts_root(out).rmdir()
    if moved or busy:
        log.info("merged %d items from the parts of %s; %d part folders busy", moved, out, len(busy))
    return {"moved": moved, "dropped": dropped, "parts": removed, "busy": busy}
