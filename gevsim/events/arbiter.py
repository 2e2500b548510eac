"""The AER arbiter and bus: one request per pixel, reset on the acknowledge (issue 34, item 3).

A pixel whose comparator fires raises a request and holds it until the arbiter acknowledges it;
only then is its change amplifier reset (and held in reset for the refractory period). While it
waits it cannot fire again: crossings the pixel model makes meanwhile are not queued as extra
events but counted as *unsent* (Lichtsteiner, Posch & Delbruck 2008, section III-C: "the pixel ...
is reset only when the request is acknowledged"; Boahen 2000, "Point-to-point connectivity between
neuromorphic chips using address events", IEEE TCAS-II 47(5), the 4-phase handshake). The bus then
holds at most one request per requester (a pixel, or a pixel's comparator pair per axis for
gradient events), and a waiting request's delay is bounded by what the arbitration serves first.

Arbitration (a :data:`ARBITERS` entry) picks the next request once the bus is free (one event
every 1 / ``max_rate_eps``):

- ``row_burst`` (DAVIS): a row arbiter picks a row with pending requests; every pixel of that row
  requesting at that moment is latched and read in a column burst, one address per bus slot
  (Boahen 2004, "A burst-mode word-serial address-event link", IEEE TCAS-I 51(7); the DAVIS
  readout, Brandli et al. 2014, JSSC 49(10)). The row arbiter is modelled round-robin from the row
  last served: the greedy tree arbiter of those chips can favour neighbouring rows, a fair
  arbiter is the stated approximation. Bound: a request waits at most for every other pending
  request once, (pending requests) / rate <= (requesters) / rate.
- ``row_column`` (DVS128): each event arbitrated alone, row then column, both round-robin
  (Lichtsteiner et al. 2008, Fig. 7: row and column arbiters, no burst).
- ``row_queue`` (Prophesee Gen4): a row with a request enters a first-in first-out queue of row
  requests; the row at its head is read in parallel and its events leave one per bus slot
  (Finateu et al., ISSCC 2020, "A 1280x720 back-illuminated stacked temporal contrast event-based
  vision sensor with 4.86 um pixels, 1.066 GEPS readout"; the row request queue as described in
  Prophesee's patent US 2024/0380993 A1, Finateu & Opperman).

An event's timestamp is its acknowledge time (the time its address is read).

The arbiter works on the pixel model's own crossings (each made as if acknowledged at once): a
crossing while its pixel waits, or within ``hold_s`` after its acknowledge, is not sent. After an
acknowledge the pixel model's memorised level is that of its last crossing, which is within one
threshold of the signal at the acknowledge where a chip's pixel resets exactly to it: the stated
approximation (its reach: the fraction of delivered events whose pixel had unsent crossings while it
waited, :attr:`Readout.summary`'s ``unsent``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from gevsim._portable import log_scalar
from gevsim.pixel.params import ARBITRATIONS

#: Delay histogram: bin 0 holds zero waits, bins 1.. are log-spaced from DELAY_LO_US,
#: DELAY_DECADES_PER_BIN decades each.
DELAY_BINS = 64
DELAY_LO_US = 0.1
DELAY_DECADES_PER_BIN = 0.125

_ROW_BURST, _ROW_COLUMN, _ROW_QUEUE = 0, 1, 2
LN10 = 2.302585092994046


@dataclass(frozen=True)
class Arbitration:
    """One :data:`ARBITERS` entry: the kernel's policy code and its source."""

    code: int
    source: str


#: How a chip's arbiter picks the next request (see the module docstring).
ARBITERS: dict[str, Arbitration] = {
    "row_burst": Arbitration(_ROW_BURST, "Boahen 2004 (burst-mode word-serial AER); DAVIS (Brandli et al. 2014)"),
    "row_column": Arbitration(_ROW_COLUMN, "Lichtsteiner, Posch & Delbruck 2008 (DVS128 row and column arbiters)"),
    "row_queue": Arbitration(_ROW_QUEUE, "Finateu et al. ISSCC 2020 (Prophesee Gen4); US 2024/0380993 A1"),
}

if tuple(ARBITERS) != ARBITRATIONS:
    raise ImportError(f"gevsim.pixel.params.ARBITRATIONS {ARBITRATIONS} must name ARBITERS {tuple(ARBITERS)}")


@njit(inline="always")
def _delay_bin(wait_us):
    if wait_us <= 0.0:
        return 0
    b = 1 + int(math.floor(log_scalar(max(wait_us, DELAY_LO_US) / DELAY_LO_US) / (LN10 * DELAY_DECADES_PER_BIN)))
    return min(b, DELAY_BINS - 1)


@njit(inline="always")
def _admit(r, t, p, pend, pend_t, pend_p, busy_until, row_count, row_queued, queue, q, per_row, policy, stats):
    """Request r at time t: pending unless r already waits or is held in reset (then unsent)."""
    if pend[r] != 0 or t < busy_until[r]:
        stats[0] += 1
        return
    pend[r] = 1
    pend_t[r] = t
    pend_p[r] = p
    row = r // per_row
    row_count[row] += 1
    q[2] += 1
    if policy == _ROW_QUEUE and row_queued[row] == 0:
        n = queue.shape[0]
        queue[(q[0] + q[1]) % n] = row
        q[1] += 1
        row_queued[row] = 1


@njit(inline="always")
def _next_row(policy, row_count, row_queued, queue, q, cursor):
    """The row the arbiter serves next (-1: none pending)."""
    h = row_count.shape[0]
    if policy == _ROW_QUEUE:
        while q[1] > 0:
            row = queue[q[0]]
            q[0] = (q[0] + 1) % queue.shape[0]
            q[1] -= 1
            row_queued[row] = 0
            if row_count[row] > 0:
                return row
        return -1
    for k in range(1, h + 1):
        row = (cursor[0] + k) % h
        if row_count[row] > 0:
            return row
    return -1


@njit(cache=True)
def _serve(t_in, r_in, p_in, horizon_us, end_us, final, service_us, max_delay_us, hold_us, policy, per_row,
          pend, pend_t, pend_p, busy_until, row_count, row_queued, queue, q, cursor, col_cursor, latched, burst,
          bus, out_r, out_p, out_t, stats, hist):
    """Serve requests ``r_in`` (requester ids) arriving at ``t_in`` (us, sorted) with polarities ``p_in``
    until ``horizon_us`` (every later request arrives after it; ignored when ``final``) or ``end_us``.
    Fills out_* with the acknowledged events in time order; returns how many. ``bus[0]``: when the bus
    is next free. ``q``: (head, length) of the row queue and the pending total. ``burst``: (row,
    position, length) of the column burst under way. ``stats``: unsent,
    delayed, dropped, total delay (us), longest delay (us)."""
    n = t_in.shape[0]
    i = 0
    m = 0
    limit = end_us if final else min(horizon_us, end_us)
    while True:
        if burst[2] <= burst[1] and q[2] == 0:  # idle: the bus waits for the next request
            if i >= n:
                break
            bus[0] = max(bus[0], np.float64(t_in[i]))
        while i < n and t_in[i] <= bus[0]:
            _admit(r_in[i], np.float64(t_in[i]), p_in[i], pend, pend_t, pend_p, busy_until, row_count, row_queued,
                   queue, q, per_row, policy, stats)
            i += 1
        if bus[0] >= limit:
            break
        if burst[1] >= burst[2] and q[2] == 0:  # every arrival so far was unsent: idle until the next one
            continue
        if burst[1] >= burst[2]:  # pick a row (and latch it, in burst modes)
            row = _next_row(policy, row_count, row_queued, queue, q, cursor)
            if row < 0:  # cannot happen: every pending request's row is found
                break
            cursor[0] = row
            burst[0], burst[1], burst[2] = row, 0, 0
            if policy == _ROW_COLUMN:  # one pixel: the column arbiter's next after its last
                for k in range(1, per_row + 1):
                    c = (col_cursor[row] + k) % per_row
                    if pend[row * per_row + c] == 1:
                        latched[0] = row * per_row + c
                        col_cursor[row] = c
                        burst[2] = 1
                        break
            else:
                for c in range(per_row):
                    if pend[row * per_row + c] == 1:
                        pend[row * per_row + c] = 2  # latched: read in this burst
                        latched[burst[2]] = row * per_row + c
                        burst[2] += 1
        r = latched[burst[1]]
        burst[1] += 1
        row = r // per_row
        wait = bus[0] - pend_t[r]
        pend[r] = 0
        row_count[row] -= 1
        q[2] -= 1
        if burst[1] >= burst[2] and policy == _ROW_QUEUE and row_count[row] > 0 and row_queued[row] == 0:
            queue[(q[0] + q[1]) % queue.shape[0]] = row  # requests that came during the burst: to the back
            q[1] += 1
            row_queued[row] = 1
        if wait > max_delay_us:
            stats[2] += 1
            busy_until[r] = bus[0] + hold_us  # the pixel is reset without its event being read
            continue
        out_r[m] = r
        out_p[m] = pend_p[r]
        out_t[m] = np.int64(math.floor(bus[0]))
        m += 1
        busy_until[r] = bus[0] + hold_us
        if wait > 0.0:
            stats[1] += 1
            stats[3] += wait
            stats[4] = max(stats[4], wait)
        hist[_delay_bin(wait)] += 1
        bus[0] += service_us
    while i < n:  # arrivals beyond the limit (only at the end): they wait too, one per requester
        _admit(r_in[i], np.float64(t_in[i]), p_in[i], pend, pend_t, pend_p, busy_until, row_count, row_queued,
               queue, q, per_row, policy, stats)
        i += 1
    return m, i


def delay_quantile_us(hist: np.ndarray, q: float) -> float:
    """The ``q`` quantile of the delays in histogram ``hist`` (upper edge of its bin; 0 for zero waits)."""
    total = int(hist.sum())
    if total == 0:
        return 0.0
    b = int(np.searchsorted(np.cumsum(hist), q * total, side="left"))
    return 0.0 if b == 0 else DELAY_LO_US * 10 ** (b * DELAY_DECADES_PER_BIN)
