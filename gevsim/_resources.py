"""What this machine has: physical memory and free disk space (for checks before long runs)."""

from __future__ import annotations

import errno
import os
import shutil
from pathlib import Path


def physical_memory_bytes() -> int | None:
    """Installed memory in bytes (None where the platform does not say)."""
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        return None


def address_space_limit_bytes() -> int | None:
    """This process's address-space limit (``ulimit -v``, RLIMIT_AS) in bytes; None where there is none."""
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, ValueError, OSError):
        return None
    return None if soft == resource.RLIM_INFINITY or soft < 0 else int(soft)


def usable_memory() -> tuple[int | None, str]:
    """The memory a request may take, and how to say where that bound comes from: installed memory, or the
    process's ``ulimit -v`` where that is lower."""
    have, limit = physical_memory_bytes(), address_space_limit_bytes()
    if limit is not None and (have is None or limit < have):
        return limit, "this process may use (ulimit -v)"
    return have, "this machine has"


def free_disk_bytes(path: str | os.PathLike) -> int | None:
    """Free bytes on the file system that holds ``path`` (its nearest existing parent); None if unknown."""
    p = Path(path).absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    try:
        return int(shutil.disk_usage(p).free)
    except OSError:
        return None


#: Free space an output leaves on its disk while it is written. HDF5 writes its metadata and chunk caches
#: later, when it decides (the default chunk cache is 1 MiB per dataset; a file has a few), and
#: dv-processing writes an AEDAT4 file's index when it closes: those writes must still fit, because a
#: failure inside them crashes h5py or aborts dv-processing's C++ (issue 24 #9).
HEADROOM_BYTES = 8 * 2**20


def ensure_room(path: str | os.PathLike, nbytes: int) -> None:
    """Raise ``OSError(ENOSPC)`` naming ``path`` unless ``nbytes`` more (an upper bound) plus
    :data:`HEADROOM_BYTES` fit on its disk; nothing where the free space is unknown."""
    free = free_disk_bytes(path)
    if free is not None and free < int(nbytes) + HEADROOM_BYTES:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), os.fspath(path))


def gib(n_bytes: float) -> str:
    """``n_bytes`` as a short human-readable size."""
    for unit, size in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n_bytes >= size:
            return f"{n_bytes / size:.3g} {unit}"
    return f"{int(n_bytes)} B"
