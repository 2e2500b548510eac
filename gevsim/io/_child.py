"""Run a writer whose library may kill the process in a child process of its own.

dv-processing writes AEDAT4 files from a thread of its own and calls ``std::terminate`` when a write
fails (a disk that fills during the export): the process aborts with SIGABRT, nothing can catch it, and
the staged file is left behind (issue 24 #9). In a forked child the abort ends only the child; the parent
sees how it ended, removes the stage and says what happened in one line.
"""

from __future__ import annotations

import errno
import multiprocessing
import os
import signal
from collections.abc import Callable
from typing import Any

from gevsim import _resources


def _child(conn: Any, fn: Callable[..., Any], args: tuple) -> None:
    try:
        result = ("ok", fn(*args))
    except BaseException as exc:  # sent to the parent, which raises it
        result = ("error", exc)
    try:
        conn.send(result)
    except Exception as exc:  # an unpicklable result or exception
        conn.send(("error", RuntimeError(f"{type(exc).__name__}: {exc}")))
    conn.close()


def run_in_child(fn: Callable[..., Any], *args: Any, target: str | os.PathLike) -> Any:
    """``fn(*args)`` in a forked child process; its result, or its exception raised here. A child killed by a
    signal raises ``OSError(ENOSPC)`` naming ``target`` where ``target``'s disk has less than
    :data:`~gevsim._resources.HEADROOM_BYTES` free (the likely cause), else ``OSError(EIO)`` naming the
    signal. Without ``fork`` (not POSIX) ``fn`` runs in this process."""
    if "fork" not in multiprocessing.get_all_start_methods():
        return fn(*args)
    ctx = multiprocessing.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(send, fn, args), daemon=True)
    proc.start()
    send.close()
    try:
        try:
            kind, value = recv.recv()
        except EOFError:  # the child died without a word
            kind, value = "died", None
        proc.join()
    finally:
        recv.close()
        if proc.is_alive():  # interrupted here: the child goes too
            proc.kill()
            proc.join()
    if kind == "ok":
        return value
    if kind == "error":
        raise value
    free = _resources.free_disk_bytes(target)
    if free is not None and free < _resources.HEADROOM_BYTES:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), os.fspath(target))
    code = -(proc.exitcode or 0)
    name = signal.Signals(code).name if code in signal.valid_signals() else str(proc.exitcode)
    raise OSError(errno.EIO, f"the writer's process died ({name})", os.fspath(target))
