"""Close an HDF5 file that is being thrown away, even after a failed write (a full disk).

When a write fails with ENOSPC, HDF5 still holds dirty chunks and metadata in its caches. Closing the
file flushes them, fails again, and leaves the dataset identifiers half freed: h5py then segfaults when
it collects them (issue 24, defect #9). A file that will be deleted anyway needs none of those bytes, so
its descriptor is first pointed at the null device: the final flush succeeds (into nothing) and HDF5
frees every identifier cleanly. The staged file is then removed by its owner. A file being kept is
flushed before it is closed (:func:`close_h5`), so that a full disk fails while the file is still whole.

Even so, HDF5 writes cached chunks and metadata whenever it likes (also while h5py frees objects, where a
failure is not even raised), and a study's workers fill one disk together: a run refused at that point
could still crash. So every write is first checked against the free space (:func:`ensure_room`), and a
file refuses new data while less than :data:`HEADROOM_BYTES` would stay free, before HDF5 sees any of it.
"""

from __future__ import annotations

import contextlib
import errno
import os

import h5py

from gevsim._resources import HEADROOM_BYTES, ensure_room  # noqa: F401 (re-exported)


def disk_error(exc: BaseException, path: str | os.PathLike | None) -> OSError | None:
    """``OSError(errno, strerror, path)`` for an error whose message carries a full disk's (or a quota's,
    a read-only file system's) text, as h5py's RuntimeError and OpenEXR's do; None for any other."""
    for code in (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EIO, errno.EFBIG):
        if os.strerror(code) in str(exc):
            return OSError(code, os.strerror(code), None if path is None else os.fspath(path))
    return None


def close_h5(file: h5py.File, path: str | os.PathLike) -> None:
    """Close ``file`` (the stage of ``path``) after a flush: a full disk then fails in the flush, with every
    identifier still open (:func:`discard_h5` can close it), not inside ``close``, after which h5py's
    identifiers are half freed and touching the file again crashes. A full disk raises OSError."""
    try:
        file.flush()
    except BaseException as exc:  # h5py: "Unable to flush file (... errno = 28, ... No space left on device)"
        _sink(file)  # at once: h5py objects freed from here on would try to write, fail and break the file
        error = disk_error(exc, path) if isinstance(exc, RuntimeError) else None
        if error is None:
            raise
        raise error from exc
    file.close()


def discard_h5(file: h5py.File | None) -> None:
    """Close ``file`` (opened for writing with HDF5's default driver) without writing anything more to it;
    its contents become garbage, so call this only for a file that is about to be deleted."""
    if file is None or not file.id.valid:
        return
    _sink(file)
    with contextlib.suppress(Exception):
        file.close()


def _sink(file: h5py.File) -> None:
    """Point ``file``'s descriptor at the null device: every later write of HDF5 succeeds into nothing."""
    with contextlib.suppress(Exception):  # the default (sec2) driver: the handle is a POSIX descriptor
        fd = file.id.get_vfd_handle()
        if isinstance(fd, int) and fd >= 0:
            null = os.open(os.devnull, os.O_RDWR)
            try:
                os.dup2(null, fd)
            finally:
                os.close(null)


def sink_path(path: str | os.PathLike) -> int:
    """Point every descriptor this process holds on ``path`` at the null device (found in /proc/self/fd; none
    where that does not exist): a writer that is thrown away then closes without writing to a full disk, for
    writers whose descriptor is not exposed (dv-processing, which aborts the process when a write fails).
    Returns how many descriptors were redirected."""
    target, done = os.path.realpath(path), 0
    with contextlib.suppress(OSError):
        for name in os.listdir("/proc/self/fd"):
            with contextlib.suppress(OSError, ValueError):
                if os.readlink(f"/proc/self/fd/{name}") == target:
                    null = os.open(os.devnull, os.O_RDWR)
                    try:
                        os.dup2(null, int(name))
                        done += 1
                    finally:
                        os.close(null)
    return done
