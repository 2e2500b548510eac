"""Scene input files are read only when they are regular files of bounded size (issue 24 #12).

Every file a scene is made of is hashed into the keys of renders, study runs and
dataset sequences (:mod:`gevsim.render.inputs`). A name that points at a device
(``/dev/zero``), a FIFO or a folder would make that hash read for ever or block
on ``open``, and a huge file would take minutes: both are refused from
``os.stat`` before anything is opened (:func:`check_input_file`), and
:func:`sha256_of` opens without blocking and checks the open file again.
"""

from __future__ import annotations

import hashlib
import os
import stat
from pathlib import Path

from gevsim.errors import ConfigError

__all__ = ["MAX_INPUT_BYTES", "check_input_file", "sha256_of"]

#: Largest scene input file (texture, mesh, helper module, XML) hashed: 4 GiB, a few seconds of hashing.
MAX_INPUT_BYTES = 4 << 30


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a plain file"


def _check(st: os.stat_result, path: str | os.PathLike, source: str | None, key: str | None) -> None:
    if not stat.S_ISREG(st.st_mode):
        raise ConfigError(f"names {os.fspath(path)}, {_kind(st.st_mode)}, not a regular file", source=source,
                          key=key)
    if st.st_size > MAX_INPUT_BYTES:
        raise ConfigError(f"names {os.fspath(path)} of {st.st_size} bytes, over the limit of {MAX_INPUT_BYTES} bytes "
                          "for a scene input file", source=source, key=key)


def check_input_file(path: str | os.PathLike, *, source: str | None = None, key: str | None = None) -> bool:
    """Whether ``path`` exists (following symlinks); :class:`ConfigError` where it is not a regular file or is
    larger than :data:`MAX_INPUT_BYTES`. Only ``os.stat``: nothing is opened, so a FIFO cannot block."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return False
    _check(st, path, source, key)
    return True


def sha256_of(path: str | os.PathLike, *, source: str | None = None, key: str | None = None) -> str:
    """SHA-256 of a regular file's contents. Opened with ``O_NONBLOCK`` and checked on the open descriptor, so
    a file swapped for a FIFO or device after :func:`check_input_file` is refused, not read for ever.
    ``OSError`` where it cannot be opened or read."""
    fd = os.open(Path(path), os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    with open(fd, "rb", closefd=True) as fh:
        _check(os.fstat(fd), path, source, key)
        h = hashlib.sha256()
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()
