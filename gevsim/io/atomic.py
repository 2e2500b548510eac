"""Atomic outputs: everything is written under a temporary name beside its target and
renamed onto it only when complete (:mod:`gevsim.io.staging`, re-exported here), so a failed or
interrupted run leaves no partial output and an earlier result survives until the new one is complete.

This module adds what needs :mod:`gevsim.io.ownership`: :func:`atomic_dir` (a folder, replaced
only where gevsim owns it when a ``kind`` is given) and :func:`exclusive` (one run at a time
writes into an output folder).
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import threading
from collections.abc import Iterable, Iterator
from pathlib import Path

from gevsim.errors import ConfigError
from gevsim.io import mark, ownership
from gevsim.io.staging import (  # noqa: F401 (re-exported: they lived here)
    _STAGE,
    GRACE_S,
    LOCK_NAME,
    MANIFEST,
    STALE_AFTER_S,
    TAG,
    Staged,
    _staged,
    atomic_path,
    atomic_write_text,
    current_umask,
    fcntl,
    is_stale,
    remove_stale,
    sweep_stale,
)


class FolderBusy(ConfigError):
    """Another gevsim process holds the folder's lock (:func:`exclusive`): a run that may wait and try again
    (the merge of a study's or a dataset's parts) tells this from any other refusal."""


_held_lock = threading.Lock()
_held: dict[str, list] = {}  # folder -> [descriptor, depth, kind]: this process's locks


@contextlib.contextmanager
def atomic_dir(folder: str | os.PathLike, *, kind: str | None = None,
               inputs: Iterable[str | os.PathLike | None] = ()) -> Iterator[Path]:
    """Yield an empty staging folder that replaces ``folder`` when the block succeeds.

    With ``kind`` (an output the user named: ``render``, ``reconstruction``, ``validation``), replace only
    a missing or empty folder or an earlier gevsim output of that kind holding exactly what its mark
    records, and none that is or holds one of ``inputs`` (:func:`gevsim.io.ownership.check_folder`, checked
    again before the swap); the stage gets the mark of that kind, recording every file and folder written
    in it (:func:`gevsim.io.mark.write_mark`), before it replaces the folder. ``kind`` None (a folder
    inside an output gevsim owns) replaces whatever is there.
    """
    folder = Path(folder)
    if kind is not None:
        ownership.check_folder(folder, kind, inputs=inputs)
        ownership.sweep_beside(folder)
    with _staged(folder, folder=True) as stage:
        yield stage
        if kind is not None:
            mark.write_mark(stage, kind)
            ownership.check_folder(folder, kind, inputs=inputs)


def _open_lock(folder: Path) -> int:
    """Open (or create) ``folder``'s lock file: a plain file with one link, never followed through a
    symbolic link (a planted link would have its target truncated)."""
    lock = folder / LOCK_NAME
    try:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC, 0o666)
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise ConfigError(f"{LOCK_NAME} is a symbolic link; gevsim does not follow it: remove it or choose "
                              "another output folder", source=str(folder)) from None
        raise ConfigError(f"cannot write here ({exc.strerror or exc})", source=str(folder)) from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode) or st.st_nlink != 1:
        os.close(fd)
        raise ConfigError(f"{LOCK_NAME} is not a plain file gevsim made (a device, pipe or hard link); remove it "
                          "or choose another output folder", source=str(folder))
    return fd


@contextlib.contextmanager
def exclusive(folder: str | os.PathLike, *, what: str = "run", kind: str | None = None) -> Iterator[Path]:
    """Hold ``folder``'s lock file (:data:`LOCK_NAME`, created with the folder) for the block: one
    gevsim run at a time writes into an output folder. A second process is refused at once with a
    :class:`~gevsim.errors.ConfigError` naming the folder (and the holder's process id); the same
    process may enter again (a study's run and its report). The lock dies with its process, kill -9
    included, so nothing needs cleaning up. The lock file is never followed through a link.

    With ``kind`` (``study``, ``dataset``), the folder must be missing, empty or an earlier gevsim output
    of that kind whose files are what its mark records (:func:`gevsim.io.ownership.check_folder`, before
    anything is created, and again under the lock). Its mark is open while the lock is held
    (:func:`gevsim.io.mark.open_mark`) and records every file and folder there when the outermost block
    ends without an error (:func:`gevsim.io.mark.write_mark`); a run that fails or is killed leaves it open.
    """
    folder = Path(folder)
    if kind is not None and os.path.realpath(folder) not in _held:
        found = mark.read_mark(folder) if folder.is_dir() else None
        if not (found and found["kind"] == kind and found.get("open") is True):  # one writing now: checked locked
            ownership.check_folder(folder, kind)
        ownership.sweep_beside(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot write here ({exc.strerror or exc})", source=str(folder)) from None
    key = os.path.realpath(folder)
    with _held_lock:
        mine = _held.get(key)
        if mine is not None:
            mine[1] += 1
    if mine is None:
        fd = _open_lock(folder)
        if fcntl is not None:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                holder, held_by = "", what
                with contextlib.suppress(OSError, ValueError, IndexError):  # "PID KIND": the holder's own words
                    pid, *kind_words = os.pread(fd, 64, 0).decode().split()
                    holder = f" (process {int(pid)})"
                    held_by = kind_words[0] if kind_words and kind_words[0].isalpha() else what
                os.close(fd)
                if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN):
                    raise ConfigError(f"cannot lock {LOCK_NAME} ({exc.strerror or exc})", source=str(folder)) from None
                raise FolderBusy(f"another gevsim {held_by} is writing into this folder{holder}; wait for it to "
                                 "finish or choose another --out", source=str(folder)) from None
        with contextlib.suppress(OSError):
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()} {what}\n".encode(), 0)
        try:
            if kind is not None:
                ownership.check_folder(folder, kind)  # again, now that no other gevsim run can write here
                mark.open_mark(folder, kind)
        except BaseException:
            os.close(fd)
            raise
        with _held_lock:
            _held[key] = [fd, 1, kind]
    ended = False
    try:
        yield folder
        ended = True
    finally:
        with _held_lock:
            entry = _held[key]
            entry[1] -= 1
            if entry[1] == 0:
                del _held[key]
        if entry[1] == 0:
            try:
                if ended and entry[2] is not None:
                    mark.write_mark(folder, entry[2])  # the run ended well: everything here is its own
            except OSError as exc:  # the mark stays open: the next run still resumes
                raise ConfigError(f"cannot record what this run wrote in {mark.MARK} ({exc.strerror or exc})",
                                  source=str(folder)) from None
            finally:
                os.close(entry[0])
