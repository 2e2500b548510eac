"""Staged outputs: everything is written under a temporary name beside its target and
renamed onto it only when complete, so a failed or interrupted run leaves no partial
output and an earlier result survives until the new one is complete.

:class:`Staged` is the one mechanism; :func:`atomic_path` (a file),
:func:`gevsim.io.atomic.atomic_dir` (a folder) and :class:`~gevsim.io.hdf5.EventWriter`
(a file kept open across calls) use it. This module knows nothing of which outputs gevsim
owns (:mod:`gevsim.io.ownership`, which writes its marks with it).

A stage is named ``.<target name>.gevsim-<8 random characters><suffix>`` and is held
with an exclusive ``flock`` while it exists, so a stage that nobody holds is the
leftover of a killed process (kill -9 runs no cleanup). A new stage of the same
target removes such leftovers first (:func:`remove_stale`), and studies, datasets and
the render cache sweep their folders (:func:`sweep_stale`); a stage a live process
holds is never touched, so concurrent writers are safe. A committed output has the
mode the process's umask gives new files and folders (the stage itself is 0600/0700).
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import re
import shutil
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from gevsim.errors import ConfigError

fcntl: Any
try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: no locks, leftovers are recognised by age alone
    fcntl = None

log = logging.getLogger(__name__)

#: The JSON summary of a render or reconstruction folder (ownership is :data:`gevsim.io.ownership.MARK`).
MANIFEST = "manifest.json"
#: What every stage name carries after ``.<target name>.``.
TAG = "gevsim-"
_STAGE = re.compile(r"^\.(?P<name>.+)\." + TAG + r"[a-z0-9_]{8}(?P<suffix>\.[A-Za-z0-9_]+)?$")
#: The lock file of an output folder that one run at a time writes (:func:`gevsim.io.atomic.exclusive`).
LOCK_NAME = ".gevsim.lock"
_umask_lock = threading.Lock()
#: An unlocked stage younger than this is left alone: a new stage is locked within microseconds of
#: being created, and this margin covers that instant.
GRACE_S = 1.0
#: Where locks cannot be taken (no fcntl, or a file system that refuses them), a stage counts as a
#: leftover only when it is older than this.
STALE_AFTER_S = 3600.0


def current_umask() -> int:
    """The process's umask (from /proc where it says, so no thread ever sees a changed one)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    with _umask_lock:
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


def _follow_umask(path: Path, folder: bool) -> None:
    """Give a stage the mode a plain ``open``/``mkdir`` would have (mkstemp/mkdtemp make 0600/0700)."""
    os.chmod(path, (0o777 if folder else 0o666) & ~current_umask())


def _hold(fd: int) -> int | None:
    """Lock ``fd`` exclusively (the lock lives as long as the descriptor); None where locks are not to be had."""
    if fcntl is None:
        os.close(fd)
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    return fd


def _release(fd: int | None) -> None:
    if fd is not None:
        with contextlib.suppress(OSError):
            os.close(fd)


def is_stale(path: str | os.PathLike, *, now: float | None = None) -> bool:
    """Whether a stage is a dead process's leftover: nobody holds its lock (or, without locks, it is
    older than :data:`STALE_AFTER_S`), and it is older than :data:`GRACE_S`."""
    path = Path(path)
    try:
        age = (time.time() if now is None else now) - path.lstat().st_mtime
    except OSError:
        return False
    if age < GRACE_S:
        return False
    if fcntl is None:
        return age > STALE_AFTER_S
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        return exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN) and age > STALE_AFTER_S
    finally:
        os.close(fd)
    return True


def _remove(path: Path) -> None:
    """Remove a leftover stage; a leftover ``.old`` whose target is missing is put back first (a swap
    killed half way)."""
    match = _STAGE.match(path.name)
    if match and match["suffix"] == ".old" and path.is_dir():
        target, kept = path.parent / match["name"], path / "x"
        if not os.path.lexists(target) and os.path.lexists(kept):
            os.replace(kept, target)
            log.warning("restored %s from %s (a folder swap was interrupted)", target, path)
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
    log.info("removed %s, left by an interrupted run", path)


def _try_remove(path: Path) -> bool:
    try:
        _remove(path)
    except OSError as exc:  # a read-only folder: leave it, as before
        log.info("cannot remove %s, left by an interrupted run (%s)", path, exc.strerror or exc)
        return False
    return not os.path.lexists(path)


def remove_stale(target: str | os.PathLike) -> list[Path]:
    """Remove the leftover stages of ``target`` (:func:`is_stale`); returns what was removed."""
    target = Path(target)
    removed = []
    with contextlib.suppress(OSError):
        for entry in os.scandir(target.parent):
            match = _STAGE.match(entry.name)
            if match and match["name"] == target.name and is_stale(entry.path) and _try_remove(Path(entry.path)):
                removed.append(Path(entry.path))
    return removed


def sweep_stale(folder: str | os.PathLike, *, recursive: bool = True) -> list[Path]:
    """Remove every leftover stage under ``folder`` (:func:`is_stale`); returns what was removed."""
    folder = Path(folder)
    removed: list[Path] = []
    if not folder.is_dir():
        return removed
    for dirpath, dirnames, filenames in os.walk(folder):
        for name in dirnames + filenames:
            path = Path(dirpath) / name
            if _STAGE.match(name) and is_stale(path) and _try_remove(path):
                removed.append(path)
        dirnames[:] = [d for d in dirnames if recursive and not _STAGE.match(d)]
    return removed


class Staged:
    """A temporary file or folder beside ``target`` that replaces it on :meth:`commit`.

    Parameters
    ----------
    target : path of the output.
    folder : stage a folder (else a file).
    suffix : of the temporary name (default: the target's suffix, or ``.tmp``).

    The temporary name is ``.<target name>.gevsim-XXXXXXXX<suffix>`` and the stage is
    locked while it exists; leftovers of killed processes (stages nobody holds) are
    removed first (:func:`remove_stale`).
    """

    def __init__(self, target: str | os.PathLike, *, folder: bool = False, suffix: str | None = None):
        self.target = Path(target)
        self.folder = folder
        self._fd = None
        prefix = f".{self.target.name}.{TAG}"
        suffix = suffix or (".tmp" if folder else self.target.suffix or ".tmp")
        try:
            self.target.parent.mkdir(parents=True, exist_ok=True)
            remove_stale(self.target)
            if folder:
                self.path = Path(tempfile.mkdtemp(prefix=prefix, suffix=suffix, dir=self.target.parent))
                self._fd = _hold(os.open(self.path, os.O_RDONLY))
            else:
                fd, tmp = tempfile.mkstemp(prefix=prefix, suffix=suffix, dir=self.target.parent)
                self.path = Path(tmp)
                self._fd = _hold(fd)
        except OSError as exc:  # where the user asked for output: an input error, not a bug
            raise ConfigError(f"cannot write here ({exc.strerror or exc})", source=str(self.target)) from None

    def commit(self) -> None:
        """Rename the stage onto the target; a folder target is swapped (restored if that fails)."""
        try:
            _follow_umask(self.path, self.folder)  # outputs get the mode the user's umask gives
            if not (self.folder and self.target.is_dir()):
                os.replace(self.path, self.target)
                return
            old = Path(tempfile.mkdtemp(prefix=f".{self.target.name}.{TAG}", suffix=".old", dir=self.target.parent))
            held = _hold(os.open(old, os.O_RDONLY))
            try:
                os.replace(self.target, old / "x")
                try:
                    os.replace(self.path, self.target)
                except BaseException:
                    os.replace(old / "x", self.target)
                    raise
                shutil.rmtree(old, ignore_errors=True)
            finally:
                _release(held)
        finally:
            _release(self._fd)
            self._fd = None

    def discard(self) -> None:
        """Remove the stage; the target is untouched."""
        if self.folder:
            shutil.rmtree(self.path, ignore_errors=True)
        else:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.path)
        _release(self._fd)
        self._fd = None


@contextlib.contextmanager
def _staged(target: str | os.PathLike, *, folder: bool, suffix: str | None = None) -> Iterator[Path]:
    stage = Staged(target, folder=folder, suffix=suffix)
    try:
        yield stage.path
        stage.commit()
    except BaseException:
        stage.discard()
        raise


def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> contextlib.AbstractContextManager[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` on success.

    On an exception the temporary file is removed and ``path`` is untouched.
    """
    return _staged(path, folder=False, suffix=suffix)


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)
