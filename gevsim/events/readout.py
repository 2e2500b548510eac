"""Readout: a sensor's arbiter and bus deliver at most so many events per second (issue 23).

Pixels that fire wait for the arbiter; events leave in request order, one every 1 / R seconds at
the most (R = ``max_rate_eps``): event i is read at max(t_i, t_{i-1} + 1 / R). An event that would
wait longer than ``max_delay_s`` is dropped. Under lamp flicker this decides what a DVS delivers:
100 Hz flicker at 346x260 requests 65-91 Meps (sensor-physics audit), a DAVIS346 reads about 12 Meps
(iniVation biasing guide). Delays and drops are counted, never silent, and events still queued
when a run ends are counted as pending.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gevsim.pixel.params import ReadoutParams

__all__ = ["Readout", "ReadoutParams"]


@njit(cache=True)
def _serve(t_us, service_us, max_delay_us, free_us, keep, t_out):
    """FIFO service of events requested at t_us (sorted); returns (free_us, delayed, dropped,
    total delay, longest delay) and fills keep (bool) and t_out (read time, whole us)."""
    delayed = 0
    dropped = 0
    total = 0.0
    longest = 0.0
    for i in range(t_us.shape[0]):
        t = np.float64(t_us[i])
        start = max(t, free_us)
        wait = start - t
        if wait > max_delay_us:
            keep[i] = False
            dropped += 1
            continue
        keep[i] = True
        t_out[i] = np.int64(math.floor(start))
        free_us = start + service_us
        if wait > 0.0:
            delayed += 1
            total += wait
            longest = max(longest, wait)
    return free_us, delayed, dropped, total, longest


class Readout:
    """Stateful readout of one event stream across chunks (events of a chunk in time order)."""

    def __init__(self, params: ReadoutParams):
        self.params = params
        self.free_us = -math.inf
        self.requested = self.delayed = self.dropped = self.pending = 0
        self.total_delay_us = self.longest_delay_us = 0.0

    @property
    def limited(self) -> bool:
        return math.isfinite(self.params.max_rate_eps)

    def process(self, events: np.ndarray, *, end_us: int | None = None) -> np.ndarray:
        """The events as read out: delayed to the bus's pace (``t`` in whole us), the ones that
        waited too long left out, and those read after ``end_us`` (the run's end) left out as
        pending; counts updated."""
        self.requested += len(events)
        if not self.limited or len(events) == 0:
            return events
        keep = np.empty(len(events), np.bool_)
        t_out = np.empty(len(events), np.int64)
        self.free_us, d, x, total, longest = _serve(events["t"], 1e6 / self.params.max_rate_eps,
                                                    self.params.max_delay_s * 1e6, self.free_us, keep, t_out)
        self.delayed += d
        self.dropped += x
        self.total_delay_us += total
        self.longest_delay_us = max(self.longest_delay_us, longest)
        if end_us is not None:
            late = keep & (t_out > end_us)
            self.pending += int(np.count_nonzero(late))
            keep &= ~late
        out = events[keep]
        out["t"] = t_out[keep]
        return out

    def summary(self) -> dict:
        """Counts for the run summary and the file's attributes."""
        return {"requested": self.requested, "delivered": self.requested - self.dropped - self.pending,
                "delayed": self.delayed, "dropped": self.dropped, "pending_at_end": self.pending,
                "mean_delay_us": self.total_delay_us / self.delayed if self.delayed else 0.0,
                "max_delay_us": self.longest_delay_us, "max_rate_eps": self.params.max_rate_eps}
