"""Readout: a sensor's arbiter and bus deliver at most so many events per second (issue 23).

Pixels that fire wait for the arbiter (:mod:`gevsim.events.arbiter`: one request per pixel, reset
on the acknowledge, arbitration by rows as the chip does it); one event leaves every 1 / R seconds at
the most (R = ``max_rate_eps``). An event that would wait longer than ``max_delay_s`` is dropped.
Under lamp flicker this decides what a DVS delivers:
100 Hz flicker at 346x260 requests 65-91 Meps (sensor-physics audit), a DAVIS346 reads about 12 Meps
(iniVation biasing guide). Delays and drops are counted, never silent, and events still queued
when a run ends are counted as pending.

Before the arbiter each event is delayed by the pixel's comparator and handshake: ``latency_s``
plus a normal spread of sigma ``latency_jitter_s`` (truncated at +-3 sigma and at zero delay;
Lichtsteiner et al. 2008 measure a 15 us latency floor at bright light, IEBCS defaults to 100 us
with 10 us jitter). The spread reorders events, so a chunk's delayed events are held back until no
later request can come before them. The deviate of a stream's i-th event is keyed by (key, i):
results do not depend on the chunks.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from gevsim.events import _reorder
from gevsim.events.arbiter import ARBITERS, DELAY_BINS, _serve, delay_quantile_us
from gevsim.pixel._kernels import normal, pixel_bits, stream_key
from gevsim.pixel.params import ReadoutParams

log = logging.getLogger(__name__)

#: The latency spread is truncated at this many sigma.
JITTER_TRUNCATION = 3.0

__all__ = ["READOUT_STAGES", "Readout", "ReadoutParams", "Stage", "chip_share", "log_readouts"]


def log_readouts(summaries: dict[str, dict]) -> None:
    """Log each stream's readout counts (:meth:`Readout.summary`): WARNING where events were dropped or
    filtered, where over 1 % of the crossings were not sent or still waiting at the end, or where one waited over
    a millisecond; INFO for ordinary bus traffic (a few requests in flight at the end among them); nothing
    where nothing happened. (``gevsim emulate`` prints made, delivered and lost per stream in its summary.)"""
    for stream, c in summaries.items():
        filtered = c["rate_controller_dropped"] + c["anti_flicker_dropped"]
        unsent = c.get("unsent", 0)
        if not (c["delayed"] or c["dropped"] or c["pending_at_end"] or filtered or unsent):
            continue
        lost = (c["dropped"] or filtered or unsent + c["pending_at_end"] > 0.01 * c["requested"]
                or c["max_delay_us"] > 1000.0)
        log.log(logging.WARNING if lost else logging.INFO,
                "readout of %s: %d of %d crossings delivered, %d not sent (the pixel was waiting for its "
                "acknowledge), %d delayed (mean %.3g us, max %.3g us), %d dropped, %d pixels still waiting at the end "
                "(%.3g events/s at the most), %d dropped by the rate controller, %d by the anti-flicker filter",
                stream, c["delivered"], c["requested"], unsent, c["delayed"], c["mean_delay_us"], c["max_delay_us"],
                c["dropped"], c["pending_at_end"], c["max_rate_eps"], c["rate_controller_dropped"],
                c["anti_flicker_dropped"])


def chip_share(params: ReadoutParams, *, emulated_px: int, chip_px: int) -> ReadoutParams:
    """The bus an emulation of ``emulated_px`` pixels gets of a chip of ``chip_px``: the same events per
    pixel per second, ``max_rate_eps x emulated_px / chip_px``. An emulation at a coarser resolution than
    the chip views the same field (each emulated pixel stands for chip_px / emulated_px chip pixels firing
    alike), so a 96x72 run of a DAVIS346 (12 Meps over 346x260: 133 ev/px/s) may deliver 0.92 Meps, not 12.
    The rate controller's target is shared the same way."""
    import dataclasses

    if emulated_px < 1 or chip_px < 1:
        raise ValueError(f"pixel counts must be >= 1, got {emulated_px} and {chip_px}")
    share = emulated_px / chip_px
    return dataclasses.replace(params, max_rate_eps=params.max_rate_eps * share,
                               rate_controller_eps=params.rate_controller_eps * share)


@njit(cache=True)
def _delays_us(n, first, key, latency_us, jitter_us):
    """Delays (us, float) of a stream's events first .. first + n - 1: the latency plus the
    jitter times a normal deviate keyed by (key, event index), truncated at
    +-JITTER_TRUNCATION and at 0."""
    out = np.empty(n)
    for i in range(n):
        z = 0.0
        if jitter_us > 0.0:
            z = np.float64(normal(pixel_bits(stream_key(key, first + i, 7), 0)))
            z = min(max(z, -JITTER_TRUNCATION), JITTER_TRUNCATION)
        out[i] = max(latency_us + jitter_us * z, 0.0)
    return out


class Latency:
    """The pixels' latency floor and jitter (a :data:`READOUT_STAGES` entry): each event delayed by
    ``latency_s`` plus ``latency_jitter_s`` times a truncated normal keyed by (key, event index); delayed
    events that a later request could still precede are held back."""

    def __init__(self, params: ReadoutParams, *, key: int, shape: tuple[int, int] | None):
        self.params = params
        self.key = np.uint64(key)
        self.held: np.ndarray | None = None

    def process(self, events: np.ndarray, horizon_us: float | None, first: int) -> tuple[np.ndarray, float | None]:
        p = self.params
        jitter_us = p.latency_jitter_s * 1e6
        delay = _delays_us(len(events), first, self.key, p.latency_s * 1e6, jitter_us)
        held = events[:0] if self.held is None else self.held
        keys = np.empty(len(held) + len(events), np.int64)
        _reorder.delayed_keys(held["t"], events["t"], delay, keys)
        order = _reorder.stable_order(keys)  # np.argsort(keys, kind="stable"), bit for bit
        moved = np.empty(len(keys), events.dtype)
        for name in events.dtype.names or ():
            if name == "t":
                _reorder.take(keys, keys[:0], order, moved["t"])
            else:
                _reorder.take(held[name], events[name], order, moved[name])
        if horizon_us is None:
            self.held = None
            return moved, None
        earliest = math.floor(horizon_us + max(p.latency_s * 1e6 - JITTER_TRUNCATION * jitter_us, 0.0))
        cut = int(np.searchsorted(moved["t"], earliest, side="left"))
        self.held = moved[cut:]
        return moved[:cut], earliest  # every later event comes at or after it

    def counts(self) -> dict:
        return {}


@njit(cache=True)
def _bucket(periods, counts, tokens, last, rate):
    """Each busy period's quota from a token bucket of ``rate`` tokens per period holding at most
    ``rate + 1`` (see :class:`RateController`); returns the quotas and the bucket and period after the last."""
    quota = np.empty(len(periods), np.int64)
    for j in range(len(periods)):
        idle = periods[j] - last  # periods since the last busy one, this one included
        tokens = min(tokens + rate * idle, rate + 1.0) if idle < 2**40 else rate  # the first: one period's
        quota[j] = min(counts[j], np.int64(math.floor(tokens)))
        tokens -= quota[j]
        last = periods[j]
    return quota, tokens, last


class RateController:
    """The on-chip event-rate controller (Prophesee ESP "ERC": it keeps the event rate below a target by
    dropping events; a :data:`READOUT_STAGES` entry): in each reference period [k T, (k + 1) T) holding
    n > N_k events, N_k of them are kept, spread evenly over the period's events (the i-th kept when
    floor((i + 1) N_k / n) > floor(i N_k / n)). A period is decided once every event in it is known.

    The quota is a token bucket: each period adds r = target x T tokens, a period may send floor(tokens)
    events, and what it sends is taken off; the bucket holds at most r + 1 tokens, so the fraction of r
    carries over (a quota of 0.13 events per period sends one event in every 7-8 busy periods, where
    flooring it would send none) and an idle stretch buys at most one extra event; the first period gets
    r. Over busy periods
    the delivered rate is the target to within one event (issue 36)."""

    def __init__(self, params: ReadoutParams, *, key: int, shape: tuple[int, int] | None):
        self.params = params
        self.held: np.ndarray | None = None
        self.dropped = 0
        self.tokens = 0.0  # the bucket after the last decided period
        self.last_period = np.int64(-(2**62))  # that period's index (none yet)

    def process(self, events: np.ndarray, horizon_us: float | None, first: int) -> tuple[np.ndarray, float | None]:
        p = self.params
        if self.held is not None and len(self.held):
            events = np.concatenate([self.held, events])
        period_us = p.rate_controller_period_s * 1e6
        window = np.floor(events["t"] / period_us).astype(np.int64)
        if horizon_us is not None:
            open_window = math.floor(horizon_us / period_us)
            done = window < open_window
            self.held, events, window = events[~done], events[done], window[done]
            horizon_us = open_window * period_us  # held events come out later, from there on
        else:
            self.held = None
        if len(events) == 0:
            return events, horizon_us
        starts = np.flatnonzero(np.r_[True, window[1:] != window[:-1]])
        counts = np.diff(np.r_[starts, len(events)])
        quota, self.tokens, self.last_period = _bucket(window[starts], counts, self.tokens, self.last_period,
                                                       p.rate_controller_eps * p.rate_controller_period_s)
        allowed = np.repeat(quota, counts)
        n = np.repeat(counts, counts)
        rank = np.arange(len(events)) - np.repeat(starts, counts)
        keep = (n <= allowed) | ((rank + 1) * allowed // n > rank * allowed // n)
        self.dropped += int(np.count_nonzero(~keep))
        return events[keep], horizon_us

    def counts(self) -> dict:
        return {"rate_controller_dropped": self.dropped}


class AntiFlickerStage:
    """The on-chip anti-flicker filter (:mod:`gevsim.events.antiflicker`; a :data:`READOUT_STAGES` entry)."""

    def __init__(self, params: ReadoutParams, *, key: int, shape: tuple[int, int] | None):
        if shape is None:
            raise ValueError("the anti-flicker filter needs the sensor's shape=(H, W)")
        from gevsim.events.antiflicker import AntiFlicker

        self.filter = AntiFlicker(shape, params)

    def process(self, events: np.ndarray, horizon_us: float | None, first: int) -> tuple[np.ndarray, float | None]:
        return self.filter.process(events), horizon_us

    def counts(self) -> dict:
        return {"anti_flicker_dropped": self.filter.dropped}


@dataclass(frozen=True)
class Stage:
    """One entry of :data:`READOUT_STAGES`: whether a readout has it, its class and its source."""

    enabled: Callable[[ReadoutParams], bool]
    build: Callable[..., Any]
    source: str


#: What happens to events between the comparators and the bus, in order (each stage its class and source);
#: the arbiter and bus (``max_rate_eps``) come last in :class:`Readout`. Adding a mechanism is an entry here.
READOUT_STAGES: dict[str, Stage] = {
    "latency": Stage(lambda p: p.latency_s > 0 or p.latency_jitter_s > 0, Latency,
                     "Lichtsteiner et al. 2008 (15 us minimum latency); IEBCS (latency and jitter)"),
    "anti_flicker": Stage(lambda p: p.anti_flicker, AntiFlickerStage, "Prophesee ESP documentation (AFK)"),
    "rate_controller": Stage(lambda p: math.isfinite(p.rate_controller_eps), RateController,
                             "Prophesee ESP documentation (ERC)"),
}


class Readout:
    """Stateful readout of one event stream across chunks (events of a chunk in time order): the
    :data:`READOUT_STAGES` the params enable, then the arbiter and bus (:mod:`gevsim.events.arbiter`:
    one request per pixel, reset on the acknowledge, the preset's ``arbitration``).

    Parameters
    ----------
    params : the sensor's readout.
    key : keys the latency spread (a stream's own; any integer when ``latency_jitter_s`` is 0).
    shape : (H, W) of the pixel array (the arbiter's requesters and the anti-flicker filter's blocks need it).
    hold_s : how long a pixel is held in reset after its acknowledge (the refractory period; 0: none).
    """

    def __init__(self, params: ReadoutParams, *, key: int = 0, shape: tuple[int, int] | None = None,
                 hold_s: float = 0.0):
        self.params = params
        self.stages = {name: stage.build(params, key=key, shape=shape)
                       for name, stage in READOUT_STAGES.items() if stage.enabled(params)}
        if self.limited and shape is None:
            raise ValueError("a readout with a rate limit needs the sensor's shape=(H, W) (one request per pixel)")
        self.shape = None if shape is None else (int(shape[0]), int(shape[1]))
        self.hold_us = float(hold_s) * 1e6
        self.arbiter: _ArbiterState | None = None
        self.requested = self.dropped = self.pending = 0
        self.stats = np.zeros(5)  # unsent, delayed, dropped, total delay (us), longest delay (us)
        self.hist = np.zeros(DELAY_BINS, np.int64)

    @property
    def limited(self) -> bool:
        return math.isfinite(self.params.max_rate_eps)

    def process(self, events: np.ndarray, *, end_us: int | None = None, until_us: float | None = None) -> np.ndarray:
        """The events as read out: through the enabled stages (latency, filters), then through the arbiter
        and bus (``t``: the acknowledge, in whole us; a pixel's crossings while it waits are not sent; those
        waiting too long are dropped; those not read by ``end_us``, the run's end, are pending); counts
        updated. ``until_us``: every later request comes at or after it (the chunk's end; None: this is
        the last chunk)."""
        first = self.requested
        self.requested += len(events)
        horizon: float | None = until_us
        for stage in self.stages.values():
            events, horizon = stage.process(events, horizon, first)
        if not self.limited:
            if end_us is not None and self.stages and len(events):
                late = events["t"] > end_us
                self.pending += int(np.count_nonzero(late))
                events = events[~late]
            return events
        if self.arbiter is None:
            assert self.shape is not None  # checked in __init__
            self.arbiter = _ArbiterState(self.shape, axes=2 if "axis" in (events.dtype.names or ()) else 1)
        return self.arbiter.serve(self, events, horizon=horizon, end_us=end_us)

    def summary(self) -> dict:
        """Counts for the run summary and the file's attributes: requested (the pixels' crossings) =
        unsent (the pixel was waiting or held in reset) + filtered + dropped + pending at the end + delivered."""
        filtered = {"rate_controller_dropped": 0, "anti_flicker_dropped": 0}
        for stage in self.stages.values():
            filtered.update(stage.counts())
        unsent, delayed, dropped, total, longest = self.stats
        return {"requested": self.requested,
                "delivered": self.requested - int(unsent) - int(dropped) - self.pending - sum(filtered.values()),
                **filtered, "unsent": int(unsent), "delayed": int(delayed), "dropped": int(dropped),
                "pending_at_end": self.pending,
                "mean_delay_us": total / delayed if delayed else 0.0, "max_delay_us": float(longest),
                "median_delay_us": delay_quantile_us(self.hist, 0.5),
                "p99_delay_us": delay_quantile_us(self.hist, 0.99),
                "arbitration": self.params.arbitration if self.limited else "none",
                "max_rate_eps": self.params.max_rate_eps}


class _ArbiterState:
    """The arbiter's state across chunks: each requester's pending request, the rows' counts and queue,
    the column burst under way and the bus's next free time."""

    def __init__(self, shape: tuple[int, int], *, axes: int):
        h, w = shape
        self.w, self.axes = w, axes
        self.per_row = w * axes
        n = h * self.per_row
        self.pend = np.zeros(n, np.int8)
        self.pend_t = np.zeros(n)
        self.pend_p = np.zeros(n, np.int8)
        self.busy_until = np.full(n, -np.inf)
        self.row_count = np.zeros(h, np.int64)
        self.row_queued = np.zeros(h, np.int8)
        self.queue = np.zeros(h, np.int64)
        self.q = np.zeros(3, np.int64)
        self.cursor = np.array([h - 1], np.int64)
        self.col_cursor = np.full(h, self.per_row - 1, np.int64)
        self.latched = np.zeros(self.per_row, np.int64)
        self.burst = np.zeros(3, np.int64)
        self.bus = np.array([-np.inf])

    def serve(self, readout: Readout, events: np.ndarray, *, horizon: float | None, end_us: int | None) -> np.ndarray:
        p = readout.params
        no_axis = np.empty(0, np.uint8)
        r_in = np.empty(len(events), np.int64)
        _reorder.requesters(events["y"], events["x"], events["axis"] if self.axes == 2 else no_axis, self.per_row,
                            self.axes, r_in)
        final = horizon is None
        limit_us = math.inf if horizon is None else float(horizon)
        n_out = len(events) + int(self.q[2]) + int(self.burst[2] - self.burst[1])
        out_r, out_p, out_t = np.empty(n_out, np.int64), np.empty(n_out, np.int8), np.empty(n_out, np.int64)
        m, _ = _serve(events["t"].astype(np.float64), r_in, events["p"].astype(np.int8),
                     limit_us, math.inf if end_us is None else float(end_us), final,
                     1e6 / p.max_rate_eps, p.max_delay_s * 1e6, readout.hold_us, ARBITERS[p.arbitration].code,
                     self.per_row, self.pend, self.pend_t, self.pend_p, self.busy_until, self.row_count,
                     self.row_queued, self.queue, self.q, self.cursor, self.col_cursor, self.latched, self.burst,
                     self.bus, out_r, out_p, out_t, readout.stats, readout.hist)
        if final:
            readout.pending = int(np.count_nonzero(self.pend))
        out = np.zeros(m, events.dtype)
        _reorder.addresses(out_r[:m], out_t[:m], self.per_row, self.axes, out["y"], out["x"],
                           out["axis"] if self.axes == 2 else no_axis, out["t"])
        out["p"] = out_p[:m].astype(events.dtype["p"])
        return out
