"""What this machine has: physical memory and free disk space (for checks before long runs)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path


def physical_memory_bytes() -> int | None:
    """Installed memory in bytes (None where the platform does not say)."""
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        return None


def free_disk_bytes(path: str | os.PathLike) -> int | None:
    """Free bytes on the file system that holds ``path`` (its nearest existing parent); None if unknown."""
    p = Path(path).absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    try:
        return int(shutil.disk_usage(p).free)
    except OSError:
        return None


def gib(n_bytes: float) -> str:
    """``n_bytes`` as a short human-readable size."""
    for unit, size in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n_bytes >= size:
            return f"{n_bytes / size:.3g} {unit}"
    return f"{int(n_bytes)} B"
