"""Shared driving of the event kernels: input checks, state, buffers, collection.

Events of a chunk are ordered by (timestamp, step, block, the kernel's
emission order): this order is the same whether a sequence is processed in
one call or in chunks, and for any number of threads.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from gevsim._validate import real_array
from gevsim.events import _collect
from gevsim.events._kernels import CAP, FILL, RESUME_T, START, STEP_END0
from gevsim.timebase import check_chunk

#: Bound on the events held in the kernels' buffers at once (13-14 bytes each): a chunk
#: expected to emit more is emulated in parts of fewer steps (the events are the same).
MAX_IN_FLIGHT = 1 << 23
#: Room given to each block beyond the events expected from the previous chunk.
SLACK = 1.25

#: ``kernel(a, b, us_end, buf_t, buf_x, buf_y, buf_p, buf_axis, region, order)`` runs steps [a, b) of
#: the chunk (``us_end``: their ends in whole microseconds), taking the blocks in ``order``.
Kernel = Callable[..., object]


class SampledSignal:
    """Time bookkeeping for an emulator fed with samples at increasing times.

    The first sample initialises the state (no events); each later sample ends
    a step that began at the previous one.
    """

    def __init__(self, shape):
        self.shape = tuple(int(s) for s in shape)
        self.t_s: float | None = None

    def steps(self, signal, t_s, *, name: str = "signal"):
        """Validate a chunk; return (signal (T, H, W), step starts, step ends, first-sample flag)."""
        v, t, prev = check_chunk(signal, t_s, shape=self.shape, name=name, after=self.t_s)
        real_array(v, name)
        first = self.t_s is None
        return v, prev, t, first


def round_us(t_s: np.ndarray) -> np.ndarray:
    """Times in whole microseconds, rounded as event timestamps are."""
    return np.floor(np.asarray(t_s, np.float64) * 1e6 + 0.5).astype(np.int64)


class EventBlocks:
    """Buffers of an emulator's event kernel, sized from the previous chunk.

    Block b gets room for ``SLACK`` times its events per step in the previous chunk
    (``first_per_step`` before any chunk) plus ``min_free``, the most one resumable
    unit of work can emit (a pixel's step, a row of comparators). A block that runs out
    stops before that unit; its region and the others' are moved into larger buffers
    and the kernel goes on from where each block stopped (:attr:`regrowths` counts
    this). Nothing is computed twice.
    """

    def __init__(self, nblocks: int, *, dtype: np.dtype, first_per_step: float, min_free: int,
                 max_in_flight: int = MAX_IN_FLIGHT, run: int = 1):
        self.nblocks, self.dtype = int(nblocks), np.dtype(dtype)
        self.order = _collect.interleaved(self.nblocks, run)  # blocks over threads: runs of ``run``
        self.rate = np.full(self.nblocks, float(first_per_step))  # events per step, per block
        self.min_free, self.max_in_flight = int(min_free), int(max_in_flight)
        self.gradient = "axis" in (self.dtype.names or ())
        #: Counters for benchmarks: regions grown mid-chunk, events, seconds in the kernel and in
        #: collection (gather), the largest buffers held (bytes).
        self.regrowths = 0
        self.events = 0
        self.kernel_s = 0.0
        self.collect_s = 0.0
        self.peak_buffer_bytes = 0
        self._cache: tuple[np.ndarray, ...] = (np.empty(0, np.int64),)

    def collect(self, kernel: Kernel, t_start_s: np.ndarray, t_end_s: np.ndarray) -> np.ndarray:
        """Run ``kernel`` over the steps [t_start_s, t_end_s] (in parts if many events are
        expected); return the events in time order."""
        n_steps = len(t_end_s)
        us_lo, us_hi = round_us(t_start_s), round_us(t_end_s)
        parts = max(1, math.ceil(float(self.rate.sum()) * n_steps / self.max_in_flight))
        edges = np.unique(np.linspace(0, n_steps, min(parts, max(n_steps, 1)) + 1).round().astype(int))
        # Parts are gathered straight into one output array (no concatenation), sized from the
        # expected events and grown if a part brings more.
        out = np.empty(int(self.rate.sum() * n_steps * SLACK) if len(edges) > 2 else 0, self.dtype)
        n = 0
        for a, b in zip(edges[:-1], edges[1:]):
            out, n = self._run(kernel, int(a), int(b), us_lo, us_hi, out, n)
        return out if n == len(out) else out[:n]

    def _buffers(self, n: int, *, keep: tuple[np.ndarray, ...] | None = None) -> tuple[np.ndarray, ...]:
        """Flat buffers for ``n`` events, kept for later chunks: those of earlier chunks where they
        are large enough (pages already mapped) and not ``keep`` (which still holds events), else new."""
        if len(self._cache[0]) < n or self._cache is keep:
            p_type = np.int8 if self.gradient else np.bool_
            self._cache = (np.empty(n, np.int64), np.empty(n, np.int16), np.empty(n, np.int16), np.empty(n, p_type),
                           np.empty(n if self.gradient else 0, np.uint8))
        return self._cache

    def _run(self, kernel: Kernel, a: int, b: int, us_lo: np.ndarray, us_hi: np.ndarray, out: np.ndarray,
             n: int) -> tuple[np.ndarray, int]:
        """Steps [a, b): their events go to ``out[n:]`` (a larger array where they do not fit);
        returns the output array and its new fill."""
        steps = b - a
        region = np.zeros((self.nblocks, STEP_END0 + steps), np.int64)
        region[:, CAP] = np.ceil(self.rate * steps * SLACK).astype(np.int64) + self.min_free
        region[:, START] = np.cumsum(region[:, CAP]) - region[:, CAP]
        bufs = self._buffers(int(region[:, CAP].sum()))
        order = self.order
        tick = time.perf_counter()
        while True:
            kernel(a, b, us_hi[a:b], *bufs, region, order)
            todo = region[:, RESUME_T] < steps
            if not todo.any():
                break
            fill, cap = region[:, FILL], region[:, CAP]
            done = np.maximum(region[todo, RESUME_T], 1)
            new_cap = fill.copy()
            new_cap[todo] = np.maximum.reduce([2 * cap[todo], fill[todo] + self.min_free,
                                               np.ceil(fill[todo] * steps / done * SLACK).astype(np.int64)])
            new_start = np.cumsum(new_cap) - new_cap
            grown = self._buffers(int(new_cap.sum()), keep=bufs)
            _collect.move_regions(region, new_start, *bufs, *grown)
            region[:, START], region[:, CAP] = new_start, new_cap
            bufs = grown
            self.regrowths += 1
        tock = time.perf_counter()
        self.kernel_s += tock - tick
        self.peak_buffer_bytes = max(self.peak_buffer_bytes, sum(buf.nbytes for buf in bufs) + region.nbytes)
        ends = region[:, STEP_END0:]
        per_step = np.diff(ends, axis=1, prepend=0).sum(axis=0)
        self.rate = region[:, FILL] / max(steps, 1)
        out_start = np.concatenate([[0], np.cumsum(per_step)]).astype(np.int64)
        m = int(out_start[-1])
        if n + m > len(out):
            larger = np.empty(n + m if n == 0 else max(n + m, 2 * len(out)), self.dtype)
            larger[:n] = out[:n]
            out = larger
        events = out[n:n + m]
        axis = events["axis"] if self.gradient else np.empty(0, np.uint8)
        buf_t, buf_x, buf_y, buf_p, buf_axis = bufs
        _collect.gather(buf_t, buf_x, buf_y, buf_p, buf_axis, region, out_start, us_lo[a:b], us_hi[a:b],
                        events["x"], events["y"], events["t"], events["p"], axis)
        self.collect_s += time.perf_counter() - tock
        self.events += m
        return out, n + m
