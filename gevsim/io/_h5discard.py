"""Close an HDF5 file that is being thrown away, even after a failed write (a full disk).

When a write fails with ENOSPC, HDF5 still holds dirty chunks and metadata in its caches. Closing the
file flushes them, fails again, and leaves the dataset identifiers half freed: h5py then segfaults when
it collects them (issue 24, defect #9). A file that will be deleted anyway needs none of those bytes, so
its descriptor is first pointed at the null device: the final flush succeeds (into nothing) and HDF5
frees every identifier cleanly. The staged file is then removed by its owner.
"""

from __future__ import annotations

import contextlib
import os

import h5py


def discard_h5(file: h5py.File | None) -> None:
    """Close ``file`` (opened for writing with HDF5's default driver) without writing anything more to it;
    its contents become garbage, so call this only for a file that is about to be deleted."""
    if file is None or not file.id.valid:
        return
    with contextlib.suppress(Exception):  # the default (sec2) driver: the handle is a POSIX descriptor
        fd = file.id.get_vfd_handle()
        if isinstance(fd, int) and fd >= 0:
            null = os.open(os.devnull, os.O_RDWR)
            try:
                os.dup2(null, fd)
            finally:
                os.close(null)
    with contextlib.suppress(Exception):
        file.close()
