"""The background thread of :class:`gevsim.io.hdf5.EventWriter` (see that module's notes)."""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable


class _Worker:
    """One thread that runs jobs in order from a bounded queue; the first exception it meets is kept
    (:meth:`check` raises it) and the jobs after it are dropped."""

    def __init__(self, size: int):
        self._queue: queue.Queue = queue.Queue(maxsize=size)
        self.error: BaseException | None = None
        self._stop = False
        self._thread = threading.Thread(target=self._run, name="gevsim-hdf5-writer", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while True:
            job = self._queue.get()
            try:
                if job is None:
                    return
                if self.error is None and not self._stop:
                    job()
            except BaseException as exc:  # raised again in the caller's thread
                self.error = exc
            finally:
                self._queue.task_done()

    def check(self) -> None:
        if self.error is not None:
            raise self.error

    def submit(self, job: Callable[[], object]) -> None:
        self.check()
        self._queue.put(job)

    def wait(self) -> None:
        """Block until the queued jobs are done; raise the first failure."""
        self._queue.join()
        self.check()

    def join(self, *, cancel: bool = False) -> None:
        """Run the queued jobs (drop them with ``cancel``) and end the thread."""
        self._stop = self._stop or cancel
        if self._thread.is_alive():
            self._queue.put(None)
            self._thread.join()
