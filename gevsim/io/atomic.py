"""Atomic outputs: everything is written under a temporary name beside its target and
renamed onto it only when complete, so a failed or interrupted run leaves no partial
output and an earlier result survives until the new one is complete.

:class:`Staged` is the one mechanism; :func:`atomic_path` (a file), :func:`atomic_dir`
(a folder) and :class:`~gevsim.io.hdf5.EventWriter` (a file kept open across calls)
use it.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

from gevsim.errors import ConfigError

#: The file that marks a folder as a gevsim output (written last, inside the stage).
MANIFEST = "manifest.json"


class Staged:
    """A temporary file or folder beside ``target`` that replaces it on :meth:`commit`.

    Parameters
    ----------
    target : path of the output.
    folder : stage a folder (else a file).
    suffix : of the temporary name (default: the target's suffix, or ``.tmp``).

    The temporary name starts with ``.<target name>.``, so leftovers of a killed
    process are easy to find.
    """

    def __init__(self, target: str | os.PathLike, *, folder: bool = False, suffix: str | None = None):
        self.target = Path(target)
        self.folder = folder
        prefix = f".{self.target.name}."
        suffix = suffix or (".tmp" if folder else self.target.suffix or ".tmp")
        try:
            self.target.parent.mkdir(parents=True, exist_ok=True)
            if folder:
                self.path = Path(tempfile.mkdtemp(prefix=prefix, suffix=suffix, dir=self.target.parent))
            else:
                fd, tmp = tempfile.mkstemp(prefix=prefix, suffix=suffix, dir=self.target.parent)
                os.close(fd)
                self.path = Path(tmp)
        except OSError as exc:  # where the user asked for output: an input error, not a bug
            raise ConfigError(f"cannot write here ({exc.strerror or exc})", source=str(self.target)) from None

    def commit(self) -> None:
        """Rename the stage onto the target; a folder target is swapped (restored if that fails)."""
        if not (self.folder and self.target.is_dir()):
            os.replace(self.path, self.target)
            return
        old = Path(tempfile.mkdtemp(prefix=f".{self.target.name}.", suffix=".old", dir=self.target.parent))
        os.replace(self.target, old / "x")
        try:
            os.replace(self.path, self.target)
        except BaseException:
            os.replace(old / "x", self.target)
            raise
        shutil.rmtree(old, ignore_errors=True)

    def discard(self) -> None:
        """Remove the stage; the target is untouched."""
        if self.folder:
            shutil.rmtree(self.path, ignore_errors=True)
        else:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.path)


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


@contextlib.contextmanager
def atomic_dir(folder: str | os.PathLike, *, marker: str | None = None) -> Iterator[Path]:
    """Yield an empty staging folder that replaces ``folder`` when the block succeeds.

    With ``marker`` (a file name such as ``manifest.json``), refuse to replace an existing
    folder that is not empty and holds no such file: it is not an earlier output of this kind.
    """
    folder = Path(folder)
    if marker is not None and folder.exists():
        if not folder.is_dir():
            raise ConfigError("output exists and is not a folder", source=str(folder))
        if any(folder.iterdir()) and not (folder / marker).is_file():
            raise ConfigError(f"output folder is not empty and holds no gevsim {marker}; choose another folder",
                              source=str(folder))
    with _staged(folder, folder=True) as stage:
        yield stage


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)
