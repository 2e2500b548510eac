"""Event collection: from the kernels' per-block regions to one time-ordered array.

The kernels (:mod:`gevsim.events._kernels`) leave block b's events of step t at
``[end(t - 1), end(t))`` of its region, in emission order. Events of step t are
stamped inside [t_start, t_end] of that step (rounded to the microsecond, and
clamped to the step end against a last-ulp overshoot of ``t_start + s * dt``),
so every event of step t comes before every event of step t + 1 in the order
(timestamp, step). The chunk is therefore ordered step by step, and within a
step by timestamp with ties kept in block order and emission order.
:func:`gather` does a parallel stable counting sort on the microsecond within
each step, in work items of about equal events (a stable merge sort where a step
spans many more microseconds than it has events). This is the order of one
stable sort on (timestamp, step) over the blocks taken in order, so it does not
depend on how a sequence is cut into chunks nor on the number of threads; since
blocks are consecutive pixels (rows for gradient events) it does not depend on the
block size either: it is (timestamp, step, pixel, emission).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from gevsim.events._kernels import FILL, START, STEP_END0

#: Stride of :func:`interleaved` (flicker crowds events into few steps, texture into parts of
#: the image).
_INTERLEAVE = 8


@njit(inline="always")
def _put(src, j, buf_t, buf_x, buf_y, buf_p, buf_axis, x, y, t, p, axis):
    x[j] = buf_x[src]
    y[j] = buf_y[src]
    t[j] = buf_t[src]
    p[j] = buf_p[src]
    if axis.shape[0]:
        axis[j] = buf_axis[src]


@njit(inline="always")
def _bounds(region, b, s):
    base = region[b, START]
    return base + (region[b, STEP_END0 + s - 1] if s > 0 else 0), base + region[b, STEP_END0 + s]


@njit(nogil=True, cache=True)
def plan(region, us_lo, us_hi, target):
    """Cut the gather into work items: runs of blocks of one step holding about ``target``
    events (a whole step where it spans many more microseconds than it has events: it is
    sorted). Returns (step, first block, end block, histogram offset, sorted flag) per item
    and the histogram size."""
    nblocks = region.shape[0]
    n_steps = us_lo.shape[0]
    items = np.empty((nblocks * n_steps + n_steps, 5), np.int64)
    k = 0
    h = 0
    for s in range(n_steps):
        n = region[:, STEP_END0 + s].sum() - (region[:, STEP_END0 + s - 1].sum() if s > 0 else 0)
        span = us_hi[s] - us_lo[s] + 1
        if n == 0:
            continue
        if span > 4 * n + 4096:
            items[k, 0], items[k, 1], items[k, 2], items[k, 3], items[k, 4] = s, 0, nblocks, 0, 1
            k += 1
            continue
        b0 = 0
        acc = 0
        for b in range(nblocks):
            lo, hi = _bounds(region, b, s)
            acc += hi - lo
            if acc >= target or b == nblocks - 1:
                items[k, 0], items[k, 1], items[k, 2], items[k, 3], items[k, 4] = s, b0, b + 1, h, 0
                h += span
                k += 1
                b0 = b + 1
                acc = 0
    return items[:k], h


@njit(parallel=True, nogil=True, cache=True)
def _histograms(buf_t, region, items, order, us_lo, hist):
    for j in prange(order.shape[0]):
        s, b0, b1, h0, srt = items[order[j]]
        if not srt:
            tmin = us_lo[s]
            for b in range(b0, b1):
                lo, hi = _bounds(region, b, s)
                for k in range(lo, hi):
                    hist[h0 + buf_t[k] - tmin] += 1


@njit(parallel=True, nogil=True, cache=True)
def _offsets(items, first_item, out_start, us_lo, us_hi, hist):
    """Exclusive prefix over (microsecond, item) of each step: where each item's events of
    each microsecond go (ties: earlier items, i.e. earlier blocks, first)."""
    for s in prange(out_start.shape[0] - 1):
        i0, i1 = first_item[s], first_item[s + 1]
        if i1 > i0 and not items[i0, 4]:
            run = out_start[s]
            for key in range(us_hi[s] - us_lo[s] + 1):
                for i in range(i0, i1):
                    c = hist[items[i, 3] + key]
                    hist[items[i, 3] + key] = run
                    run += c


@njit(nogil=True, cache=True)
def _stable_rank(keys):
    """np.argsort(keys, kind="mergesort"), compiled once here rather than inside :func:`_scatter`'s parallel loop
    (which compiled ~2x slower with it)."""
    return np.argsort(keys, kind="mergesort")


@njit(parallel=True, nogil=True, cache=True)
def _scatter(buf_t, buf_x, buf_y, buf_p, buf_axis, region, items, order, out_start, us_lo, hist, x, y, t, p, axis):
    for j in prange(order.shape[0]):
        s, b0, b1, h0, srt = items[order[j]]
        if not srt:
            tmin = us_lo[s]
            for b in range(b0, b1):
                lo, hi = _bounds(region, b, s)
                for k in range(lo, hi):
                    key = h0 + buf_t[k] - tmin
                    dst = hist[key]
                    hist[key] = dst + 1
                    _put(k, dst, buf_t, buf_x, buf_y, buf_p, buf_axis, x, y, t, p, axis)
        else:  # few events over a long step: a stable sort of the step's events
            o = out_start[s]
            n = out_start[s + 1] - o
            src = np.empty(n, np.int64)
            keys = np.empty(n, np.int64)
            m = 0
            for b in range(b0, b1):
                lo, hi = _bounds(region, b, s)
                for k in range(lo, hi):
                    src[m] = k
                    keys[m] = buf_t[k]
                    m += 1
            rank = _stable_rank(keys)
            for m in range(n):
                _put(src[rank[m]], o + m, buf_t, buf_x, buf_y, buf_p, buf_axis, x, y, t, p, axis)


def gather(buf_t: np.ndarray, buf_x: np.ndarray, buf_y: np.ndarray, buf_p: np.ndarray, buf_axis: np.ndarray,
           region: np.ndarray, out_start: np.ndarray, us_lo: np.ndarray, us_hi: np.ndarray,
           x: np.ndarray, y: np.ndarray, t: np.ndarray, p: np.ndarray, axis: np.ndarray) -> None:
    """Write the events of every step, in time order, to ``x, y, t, p[, axis]`` from
    ``out_start[s]`` on (``axis`` of length 0: none); step s's timestamps lie in
    [us_lo[s], us_hi[s]]. A parallel stable counting sort per step: work items of about
    equal events (runs of blocks) count their microseconds, a prefix over (microsecond,
    item) places them, and the items scatter their events."""
    total = int(out_start[-1])
    items, h = plan(region, us_lo, us_hi, max(1 << 14, total // 64))
    first_item = np.searchsorted(items[:, 0], np.arange(len(us_lo) + 1)).astype(np.int64)
    order = interleaved(len(items))
    hist = np.zeros(h, np.int64)
    _histograms(buf_t, region, items, order, us_lo, hist)
    _offsets(items, first_item, out_start, us_lo, us_hi, hist)
    _scatter(buf_t, buf_x, buf_y, buf_p, buf_axis, region, items, order, out_start, us_lo, hist, x, y, t, p, axis)


@njit(parallel=True, nogil=True, cache=True)
def move_regions(region, new_start, old_t, old_x, old_y, old_p, old_axis, new_t, new_x, new_y, new_p, new_axis):
    """Copy every block's filled part of its region to its new start (growing the buffers)."""
    for b in prange(region.shape[0]):
        a = region[b, START]
        c = new_start[b]
        for k in range(region[b, FILL]):
            new_t[c + k] = old_t[a + k]
            new_x[c + k] = old_x[a + k]
            new_y[c + k] = old_y[a + k]
            new_p[c + k] = old_p[a + k]
            if old_axis.shape[0]:
                new_axis[c + k] = old_axis[a + k]


def interleaved(n: int, run: int = 1) -> np.ndarray:
    """0, 8, 16, ..., 1, 9, ...: the order of parallel loops over steps or blocks, so that
    each thread's contiguous share of the loop mixes all parts (load balance only). With
    ``run`` > 1, runs of that many consecutive items stay together (gradient rows share
    their neighbours' samples)."""
    units = -(-n // run)
    first = np.concatenate([np.arange(r, units, _INTERLEAVE) for r in range(min(_INTERLEAVE, max(units, 1)))])
    if run == 1:
        return first
    items = (first[:, None] * run + np.arange(run)[None, :]).ravel()
    return items[items < n]
