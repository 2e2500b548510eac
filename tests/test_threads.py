"""Threads (issue 37, item 3): gevsim makes numba's OpenMP threads sleep rather than spin, never over the
user's setting, and a pool of W workers gives each floor(cores / W) numba threads (docs/api.md, "Threads")."""

import ctypes.util
import os
import subprocess
import sys

import pytest

from gevsim.experiments import executors
from gevsim.experiments.executors import make_executor, usable_cores, worker_threads

#: Load GNU OpenMP after ``import gevsim``, as numba's "omp" layer does at its first parallel call (its
#: omppool links the system's libgomp.so.1); with OMP_DISPLAY_ENV, libgomp prints the settings it read.
LOAD_LIBGOMP = "import ctypes, gevsim\nctypes.CDLL({library!r})\n"


def _env(**changes: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT")}
    return {**env, **changes}


def test_import_gevsim_makes_openmp_passive_before_libgomp_reads_it():
    # Before: no wait policy, libgomp spun 300,000 times at each barrier ("PASSIVE" displayed, yet
    # GOMP_SPINCOUNT = '300000') and 2 threads ran 5.3x slower than 1 beside other work. What libgomp itself
    # reports it read, not only the variable: no spinning.
    library = ctypes.util.find_library("gomp")
    if library is None:
        pytest.skip("no GNU OpenMP on this machine (numba uses another threading layer)")
    done = subprocess.run([sys.executable, "-c", LOAD_LIBGOMP.format(library=library)],
                          env=_env(OMP_DISPLAY_ENV="VERBOSE"), capture_output=True, text=True, check=True)
    assert "OMP_WAIT_POLICY = 'PASSIVE'" in done.stderr
    assert "GOMP_SPINCOUNT = '0'" in done.stderr


def test_a_wait_policy_the_user_set_is_kept():
    code = "import os, gevsim; print(os.environ['OMP_WAIT_POLICY'])"
    done = subprocess.run([sys.executable, "-c", code], env=_env(OMP_WAIT_POLICY="ACTIVE"), capture_output=True,
                          text=True, check=True)
    assert done.stdout.strip() == "ACTIVE"


@pytest.mark.parametrize(("cores", "workers", "threads"), [(8, 1, 8), (8, 3, 2), (8, 8, 1), (2, 4, 1), (6, 4, 1)])
def test_worker_threads_is_cores_over_workers_rounded_down_at_least_one(monkeypatch, cores, workers, threads):
    monkeypatch.setattr(executors, "usable_cores", lambda: cores)
    assert worker_threads(workers) == threads


def test_usable_cores_is_the_affinity_capped_by_a_cgroup_quota(monkeypatch, tmp_path):
    affinity = len(os.sched_getaffinity(0))
    quota = tmp_path / "cpu.max"
    monkeypatch.setattr(executors, "CGROUP_CPU_MAX", str(quota))
    monkeypatch.setattr(executors, "CGROUP_V1_QUOTA", (str(tmp_path / "none"), str(tmp_path / "none")))
    quota.write_text("max 100000\n")
    assert usable_cores() == affinity
    quota.write_text("150000 100000\n")  # docker --cpus 1.5: one whole core
    assert usable_cores() == 1
    quota.write_text("6400000 100000\n")  # 64 CPUs' quota on this machine: its own cores
    assert usable_cores() == affinity
    quota.unlink()  # cgroup v1: quota and period in two files, -1 for none
    v1 = (tmp_path / "cfs_quota_us", tmp_path / "cfs_period_us")
    monkeypatch.setattr(executors, "CGROUP_V1_QUOTA", tuple(map(str, v1)))
    v1[1].write_text("100000\n")
    v1[0].write_text("-1\n")
    assert usable_cores() == affinity
    v1[0].write_text("100000\n")
    assert usable_cores() == 1


def test_pool_workers_get_cores_over_workers_numba_threads(monkeypatch):
    # Before: every pool worker got NUMBA_NUM_THREADS=1 whatever the pool's size. The worker reads its own
    # environment (os.getenv runs there); cores are stood in for, so the arithmetic shows on any machine.
    monkeypatch.delenv("NUMBA_NUM_THREADS", raising=False)
    monkeypatch.setattr(executors, "usable_cores", lambda: 6)
    with make_executor("local", workers=2) as pool:
        assert pool.submit(os.getenv, "NUMBA_NUM_THREADS").result() == "3"


def test_pool_workers_keep_a_thread_count_the_user_set(monkeypatch):
    monkeypatch.setenv("NUMBA_NUM_THREADS", "1")
    monkeypatch.setattr(executors, "usable_cores", lambda: 6)
    with make_executor("local", workers=1) as pool:
        assert pool.submit(os.getenv, "NUMBA_NUM_THREADS").result() == "1"


def test_dask_local_cluster_tasks_run_with_cores_over_workers_threads(monkeypatch):
    # Threads of one process share numba's pool: each task sets its own thread's count (numba's is per thread).
    pytest.importorskip("dask.distributed", reason="the dask extra is not installed")
    import numba

    pool = numba.config.NUMBA_NUM_THREADS
    if pool < 2:
        pytest.skip("needs a numba pool of 2 threads to tell 1 from the default")
    monkeypatch.delenv("NUMBA_NUM_THREADS", raising=False)
    monkeypatch.setattr(executors, "usable_cores", lambda: pool)
    with make_executor("dask", workers=2, processes=False) as executor:
        assert executor.submit(numba.get_num_threads).result() == pool // 2  # numba's default: the whole pool
