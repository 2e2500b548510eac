"""Executors: a local pool's workers do not outlive the process that started them, even after kill -9; a
Dask worker that dies is a BrokenExecutor (the CLI's one line), as the local pool's is."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gevsim.experiments.executors import make_executor

PARENT = """
import os, time
from gevsim.experiments.executors import make_executor

def pid(delay):
    time.sleep(delay)
    return os.getpid()

if __name__ == "__main__":
    with make_executor("local", workers=2) as pool:
        pids = {f.result() for f in [pool.submit(pid, 1.0) for _ in range(2)]}
        print(*pids, flush=True)
        pool.submit(time.sleep, 600)  # a worker busy in a job when the parent is killed
        time.sleep(600)
"""


def alive(pid: int) -> bool:
    """Running (not gone, not a zombie nobody has reaped yet)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except FileNotFoundError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def test_pool_workers_exit_when_their_parent_is_killed(tmp_path):
    script = tmp_path / "parent.py"
    script.write_text(PARENT)
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True, cwd=tmp_path)
    try:
        workers = [int(p) for p in proc.stdout.readline().split()]
        assert len(workers) == 2 and all(alive(p) for p in workers)
        time.sleep(0.5)  # the sleep job has started in a worker
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    deadline = time.monotonic() + 10
    while any(alive(p) for p in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = [p for p in workers if alive(p)]
    for p in left:  # do not leave them behind if the test fails
        os.kill(p, signal.SIGKILL)
    assert not left, f"workers {left} outlived their parent"


def _killed(_):
    """What a Dask client raises for a task whose workers died (a nanny's restarts spent): distributed's own
    KilledWorker, raised here inside a threads-only cluster where a real death would take the test with it."""
    from types import SimpleNamespace

    from distributed.scheduler import KilledWorker

    raise KilledWorker("run_one-3f2a", SimpleNamespace(address="tcp://127.0.0.1:40000"), 3)


def test_a_dask_worker_that_dies_is_a_broken_executor_not_a_dask_traceback():
    # Killing a Dask worker during `study --executor dask` gave distributed's own traceback (issue 36); the
    # local pool's BrokenProcessPool already gave the CLI's one line ("a worker process died ...", exit 1).
    # (A real os._exit in a process worker gives the same KilledWorker: 8 s, too slow for the suite.)
    pytest.importorskip("dask.distributed", reason="the dask extra is not installed")
    from concurrent.futures import BrokenExecutor

    from gevsim.experiments.executors import run_all

    with pytest.raises(BrokenExecutor, match="a Dask worker died running run_one-3f2a"):
        with make_executor("dask", workers=1, processes=False) as executor:
            run_all(_killed, [((0,), {})], executor=executor)
