"""Executors that run dataset and sweep jobs: a local process pool or Dask distributed.

Both are ``concurrent.futures.Executor`` objects, so a runner submits
module-level functions and collects small result dicts with ``as_completed``.

The local pool uses the ``spawn`` start method: the parent has usually
imported Mitsuba/Dr.Jit (whose LLVM backend keeps a thread pool) and numba,
and forking a process with live threads can deadlock the child. A spawned
worker pays ~1-2 s of imports once, then runs any number of jobs. Workers exit
when the process that started them dies, even by kill -9 (:func:`_exit_with_parent`).

Threads (docs/api.md, "Threads"): ``W`` workers on a machine of ``C`` usable cores
(:func:`usable_cores`) each get ``max(1, C // W)`` numba threads (:func:`worker_threads`), so a
pool keeps about one busy thread per core: a process-pool worker through its environment, a Dask
``LocalCluster`` task by ``numba.set_num_threads`` in its own thread (numba counts threads per
calling thread). Workers of a Dask scheduler given by address keep their cluster's settings.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import re
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import BrokenExecutor, Executor, ProcessPoolExecutor, as_completed
from typing import Any

from gevsim.errors import ConfigError, MissingExtraError, one_line, suggest

log = logging.getLogger(__name__)


#: Thread-pool variables a worker process gets unless the parent's environment sets them: each worker's
#: BLAS/OpenMP/numba pools hold :func:`worker_threads` threads (more would oversubscribe the cores).
WORKER_THREADS_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")

#: cgroup files that cap a container's CPU time (v2 ``cpu.max``: "QUOTA PERIOD" or "max PERIOD"; v1: two files).
CGROUP_CPU_MAX = "/sys/fs/cgroup/cpu.max"
CGROUP_V1_QUOTA = ("/sys/fs/cgroup/cpu/cpu.cfs_quota_us", "/sys/fs/cgroup/cpu/cpu.cfs_period_us")


def usable_cores() -> int:
    """The cores this process may use: its CPU affinity (``taskset``, a batch system's cpuset), capped by a
    cgroup CPU quota (``docker --cpus``, a Kubernetes limit) rounded down; at least 1."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    quota = _cgroup_cpus()
    return max(1, cores if quota is None else min(cores, quota))


def _cgroup_cpus() -> int | None:
    """Whole CPUs of this container's cgroup quota, or None (no quota, or no cgroup file to read)."""
    def words(path: str) -> list[str]:
        with open(path) as f:
            return f.read().split()

    try:
        quota, period = words(CGROUP_CPU_MAX)[:2]
    except (OSError, ValueError):
        try:
            quota, period = (words(name)[0] for name in CGROUP_V1_QUOTA)
        except (OSError, IndexError):
            return None
    try:
        q, p = int(quota), int(period)
    except ValueError:  # "max": no quota
        return None
    return q // p if q > 0 and p > 0 else None


def worker_threads(workers: int) -> int:
    """numba threads for each of ``workers`` workers sharing this machine: ``usable_cores() // workers``, at
    least 1 (issue 37: with a pool of one worker per core and numba threads = cores, every study oversubscribed
    the machine)."""
    return max(1, usable_cores() // workers)


def _threads_env(threads: int) -> dict[str, str]:
    """:data:`WORKER_THREADS_ENV` at ``threads``, but for the names this process's environment sets."""
    return {name: str(threads) for name in WORKER_THREADS_ENV if name not in os.environ}


#: How often (seconds) a pool worker checks that the process that started it is alive.
PARENT_POLL_S = 0.5


def _exit_with_parent(parent_pid: int) -> None:
    """Exit this process as soon as ``parent_pid`` is no longer its parent (the parent died, even by
    kill -9, and the worker was handed to init): a pool's workers never outlive their run."""
    while True:
        if os.getppid() != parent_pid:
            os._exit(1)
        time.sleep(PARENT_POLL_S)


def _worker_init(parent_pid: int | None = None, env: dict[str, str] | None = None) -> None:
    """Process-pool initializer: runs in the spawned worker before it imports numpy or numba, and sets
    ``env`` (:func:`_threads_env`) where the environment does not. With ``parent_pid``, a daemon thread
    ends the worker when that parent dies (:func:`_exit_with_parent`)."""
    for name, value in (env or {}).items():
        os.environ.setdefault(name, value)
    if parent_pid is not None:
        threading.Thread(target=_exit_with_parent, args=(parent_pid,), name="gevsim-parent-watch",
                         daemon=True).start()


@contextlib.contextmanager
def _local(workers: int | None, scheduler: str | None, processes: bool) -> Iterator[Executor]:
    """A spawn-context ``ProcessPoolExecutor`` of ``workers`` processes (default: the usable cores), each with
    :func:`worker_threads` numba threads."""
    if scheduler is not None:
        raise ConfigError("a scheduler address needs the dask executor", key="scheduler")
    workers = workers or usable_cores()
    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                             initializer=_worker_init,
                             initargs=(os.getpid(), _threads_env(worker_threads(workers)))) as pool:
        yield pool


#: How long to wait for a Dask scheduler to answer (distributed's default is 30 s).
SCHEDULER_CONNECT_S = 10.0


@contextlib.contextmanager
def _dask(workers: int | None, scheduler: str | None, processes: bool) -> Iterator[Executor]:
    """A ``dask.distributed`` client's executor: on the scheduler at ``scheduler``, else on a new
    ``LocalCluster`` of ``workers`` one-thread workers (processes, or threads with ``processes=False``)."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise MissingExtraError("the dask executor needs dask.distributed: pip install 'gevsim[dask]'") from None
    try:
        with _dask_client(workers, scheduler, processes, Client, LocalCluster) as executor:
            yield executor
    except Exception as exc:
        dead = _dead_worker(exc)
        if dead is None:
            raise
        raise BrokenExecutor(dead) from exc


def _dead_worker(exc: BaseException) -> str | None:
    """What a Dask error says about a worker that died (killed by the kernel for memory, by a signal, or
    restarted by its nanny until the task was given up), or None where ``exc`` is about something else."""
    from distributed.scheduler import KilledWorker

    if isinstance(exc, KilledWorker):
        return f"a Dask worker died running {exc.args[0] if exc.args else 'a run'} and the task was given up"
    if isinstance(exc, RuntimeError) and re.search(r"Nanny failed to start|Worker failed to start", str(exc)):
        return f"a Dask worker could not be started or restarted ({one_line(exc)})"
    return None


@contextlib.contextmanager
def _dask_client(workers: int | None, scheduler: str | None, processes: bool, Client: Any,
                 LocalCluster: Any) -> Iterator[Executor]:
    """The executor of a client of ``scheduler`` or of a new LocalCluster (see :func:`_dask`)."""
    threads = None  # numba threads per LocalCluster task (a scheduler's workers keep their cluster's settings)
    with contextlib.ExitStack() as stack:
        if scheduler is not None:
            if workers is not None:
                log.warning("workers=%d ignored: the scheduler at %s has its own workers", workers, scheduler)
            try:
                client = stack.enter_context(Client(scheduler, timeout=SCHEDULER_CONNECT_S))
            except (OSError, ValueError, TypeError) as exc:  # unreachable (timed out), refused, a bad address
                raise ConfigError(f"cannot connect to the Dask scheduler at {scheduler!r}: {one_line(exc)}",
                                  key="--scheduler") from None
        else:
            workers = workers or usable_cores()
            cluster = stack.enter_context(LocalCluster(n_workers=workers, threads_per_worker=1, processes=processes,
                                                       dashboard_address=None))
            client = stack.enter_context(Client(cluster))
            if "NUMBA_NUM_THREADS" not in os.environ:  # else the user's count, as the local pool keeps it
                threads = worker_threads(workers)
        executor = client.get_executor()
        if threads is not None:
            executor = _NumbaThreads(executor, threads)
        try:
            yield executor
        finally:
            executor.shutdown(wait=True)


class _NumbaThreads(Executor):
    """An executor whose tasks first set numba's threads, in the thread that runs them (:class:`_WithThreads`)."""

    def __init__(self, inner: Executor, threads: int):
        self._inner, self._threads = inner, threads

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Any:
        return self._inner.submit(_WithThreads(fn, self._threads), *args, **kwargs)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        self._inner.shutdown(wait=wait)  # Dask's executor takes no cancel_futures


class _WithThreads:
    """``fn`` called after ``numba.set_num_threads(threads)`` (at most numba's pool); picklable, and named as
    ``fn`` (Dask names a task, and a dead worker's message, after it)."""

    def __init__(self, fn: Callable[..., Any], threads: int):
        self.fn, self.threads = fn, threads
        self.__name__ = getattr(fn, "__name__", type(fn).__name__)

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        import numba

        numba.set_num_threads(min(self.threads, numba.config.NUMBA_NUM_THREADS))
        return self.fn(*args, **kwargs)


#: Executor kinds: name -> ``factory(workers, scheduler, processes)``, a context manager yielding an
#: executor (colour-science's ``*_METHODS`` pattern). Adding one is a function and an entry here.
EXECUTORS: dict[str, Callable[[int | None, str | None, bool], contextlib.AbstractContextManager[Executor]]] = {
    "local": _local,
    "dask": _dask,
}
KINDS = tuple(EXECUTORS)


@contextlib.contextmanager
def make_executor(kind: str = "local", *, workers: int | None = None, scheduler: str | None = None,
                  processes: bool = True) -> Iterator[Executor]:
    """Yield an executor of kind ``kind`` (:data:`EXECUTORS`); everything it started is shut down on exit.

    Parameters
    ----------
    kind : {"local", "dask"}
        ``local``: a spawn-context ``ProcessPoolExecutor``. ``dask``: a
        ``dask.distributed`` client's executor, connected to ``scheduler`` if
        given, else to a new ``LocalCluster``.
    workers : int, optional
        Worker processes (local pool, or the LocalCluster's workers, one task
        at a time each). Default: the usable cores (:func:`usable_cores`). Each
        gets :func:`worker_threads` numba threads. Ignored with ``scheduler``.
    scheduler : str, optional
        Address of a running Dask scheduler, e.g. ``tcp://10.0.0.1:8786``.
    processes : bool
        LocalCluster only: workers in processes (default) or threads of this one.
    """
    if kind not in EXECUTORS:
        raise ConfigError(f"unknown executor {kind!r}{suggest(str(kind), KINDS)}; choose from {', '.join(KINDS)}",
                          key="executor")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ConfigError(f"must be a positive integer, got {workers!r}", key="workers")
    with EXECUTORS[kind](workers, scheduler, processes) as executor:
        yield executor


def run_all(fn: Callable[..., Any], calls: list[tuple[tuple, dict]], *, executor: Executor | None = None,
            progress: Callable[[int, int], None] | None = None, done: int = 0,
            total: int | None = None) -> list:
    """``fn(*args, **kwargs)`` for each ``(args, kwargs)`` of ``calls``: here, one after another
    (``executor`` None), or in the executor's workers. ``progress(done, total)`` is called at the
    start and as each call completes (``done`` counts work finished before). On the first
    failure, calls that have not started are cancelled and the error propagates. Returns the
    results in completion order."""
    total = done + len(calls) if total is None else total
    if executor is None:
        futures: list = []
        outcomes: Iterator = (fn(*args, **kwargs) for args, kwargs in calls)
    else:
        futures = [executor.submit(fn, *args, **kwargs) for args, kwargs in calls]
        outcomes = (future.result() for future in as_completed(futures))
    results = []
    try:
        if progress:
            progress(done, total)
        for result in outcomes:
            results.append(result)
            done += 1
            if progress:
                progress(done, total)
    finally:
        for future in futures:
            future.cancel()
    return results
