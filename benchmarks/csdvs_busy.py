"""CSDVS on an idle and on a busy machine: seconds per chunk with and without competing CPU load.

Usage: python benchmarks/csdvs_busy.py [--steps 256] [--repeat 5] [--load 2] [--load-kind spin|numba] [--per-step]

Times ``CenterSurroundEmulator.process`` on chunks of ``--steps`` steps of 10 us
(346x260, the emulation's default chunk of 256 steps) first with nothing else
started by this script, then while ``--load`` processes compete for the CPU: busy loops in
Python (``spin``) or numba programs opening parallel loops (``numba``, as other
gevsim processes do; their thread pools spin while waiting). Prints best and median
seconds per chunk and the busy / idle ratio of the medians.

``--per-step`` also times the former kernel structure (three parallel loops per
time step, kept here as a reference implementation) for comparison: each parallel
loop forks and joins numba's thread pool, and on a loaded machine every join waits
for a descheduled thread.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import time

import numpy as np
from numba import njit, prange

from gevsim.events import center_surround
from gevsim.events.center_surround import CenterSurroundEmulator, _solve
from gevsim.pixel import EventParams


@njit(parallel=True, cache=True)
def per_step_kernel(v, decay, surround, inv_x, up_x, inv_y, up_y, c, diff):
    """The pre-issue-12 structure: three parallel loops inside the loop over steps."""
    t_steps, h, w = v.shape
    tmp = np.empty((h, w))
    target = np.empty((h, w))
    for k in range(t_steps):
        for y in prange(h):
            _solve(v[k, y].astype(np.float64), tmp[y], inv_x, up_x, c)
        for x in prange(w):
            col = np.empty(h)
            _solve(tmp[:, x].copy(), col, inv_y, up_y, c)
            for y in range(h):
                target[y, x] = col[y]
        a = decay[k]
        for y in prange(h):
            for x in range(w):
                s = target[y, x] + a * (surround[y, x] - target[y, x])
                surround[y, x] = s
                diff[k, y, x] = v[k, y, x] - s


def spin():
    """Busy loop in plain Python: the competing load of ``--load-kind spin``."""
    x = 0
    while True:
        x += 1


@njit(parallel=True, cache=True)
def _parallel_sum(a):
    s = 0.0
    for i in prange(a.size):
        s += a[i]
    return s


def numba_job():
    """Another numba program on numba's default thread count, opening many short parallel loops
    (as other gevsim processes did): the competing load of ``--load-kind numba``."""
    a = np.ones(50_000)
    while True:
        _parallel_sum(a)


def time_chunks(kernel, *, shape, steps, repeat):
    """Best and median seconds per chunk of ``steps`` steps, and the events of the timed calls."""
    h, w = shape
    rng = np.random.default_rng(0)
    scene = np.log(0.05 + rng.random(shape))
    dt = 1e-5
    em = CenterSurroundEmulator(shape, EventParams(), surround_length_px=2.0, surround_tau_s=1e-3,
                                rng=np.random.default_rng(1))
    saved = center_surround.centre_minus_surround
    center_surround.centre_minus_surround = kernel
    try:
        k0 = 0
        seconds, events = [], []
        for i in range(repeat + 1):  # the first call compiles and settles the surround
            t = dt * np.arange(k0, k0 + steps)
            k0 += steps
            v = (scene[None] + 0.5 * np.sin(2 * np.pi * 100 * t)[:, None, None] * scene[None]).astype(np.float32)
            start = time.perf_counter()
            ev = em.process(v, t)
            if i:
                seconds.append(time.perf_counter() - start)
                events.append(ev)
    finally:
        center_surround.centre_minus_surround = saved
    return min(seconds), float(np.median(seconds)), np.concatenate(events)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=256)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--load", type=int, default=2, help="busy-loop processes started for the busy timing")
    ap.add_argument("--load-kind", choices=("spin", "numba"), default="spin")
    ap.add_argument("--per-step", action="store_true", help="also time the former per-step kernel")
    args = ap.parse_args()
    shape = (260, 346)
    if args.load_kind == "numba":
        _parallel_sum(np.ones(4))  # compile before the load processes start (they load the cache)
    kernels = [("one parallel loop per pass and chunk", center_surround.centre_minus_surround)]
    if args.per_step:
        kernels.append(("three parallel loops per step (before)", per_step_kernel))
    print(f"{os.cpu_count()} cores; load average {os.getloadavg()[0]:.2f} before starting; "
          f"346x260, {args.steps} steps of 10 us per chunk, {args.repeat} chunks")
    results = {}
    for label, kernel in kernels:
        idle = time_chunks(kernel, shape=shape, steps=args.steps, repeat=args.repeat)
        job = spin if args.load_kind == "spin" else numba_job
        # spawn, not fork: this process's numba thread pool is already running.
        workers = [mp.get_context("spawn").Process(target=job, daemon=True) for _ in range(args.load)]
        for p in workers:
            p.start()
        try:
            time.sleep(0.5)
            busy = time_chunks(kernel, shape=shape, steps=args.steps, repeat=args.repeat)
        finally:
            for p in workers:
                p.terminate()
            for p in workers:
                p.join()
        results[label] = (idle, busy)
        print(f"{label}: idle {idle[0]:.3f} / {idle[1]:.3f} s, busy ({args.load} x {args.load_kind}) "
              f"{busy[0]:.3f} / {busy[1]:.3f} s per chunk (best / median); busy / idle {busy[1] / idle[1]:.1f}x; "
              f"{len(idle[2])} events")
    if len(results) == 2:
        (a_idle, a_busy), (b_idle, b_busy) = results.values()
        same = np.array_equal(a_idle[2], b_idle[2]) and np.array_equal(a_busy[2], b_busy[2])
        print(f"events of the two kernels identical: {same}")


if __name__ == "__main__":
    main()
