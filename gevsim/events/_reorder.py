"""Compiled helpers of the readout: the latency stage's delay and re-sort, and the arbiter's requester ids.

A chunk of events (time-sorted) is delayed event by event, appended to the events held back from the
chunk before, and stably sorted by the new time: the order of ``np.argsort(t, kind="stable")`` on the
concatenation, bit for bit. The new times span little more than the chunk (the delays are bounded), so the
sort is a counting sort on the microsecond (O(events + microseconds)); a span much longer than the events
falls back to a merge sort. Every field is moved by the same permutation, field by field: numpy copies and
fancy-indexes packed structured arrays (13 bytes per event, no alignment) element by element, ~30-50 ns per
event, against a few here. For the same reason the arbiter's requester ids (from y, x and axis) and the
delivered events' fields (from the ids) are computed here rather than with numpy on the record fields.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def delayed_keys(held_t, t, delay_us, keys):
    """keys = held_t, then floor(t + delay_us) (us, int64): the times of the held events and of the new ones."""
    n_held = held_t.shape[0]
    for i in range(n_held):
        keys[i] = held_t[i]
    for i in range(t.shape[0]):
        keys[n_held + i] = np.int64(math.floor(np.float64(t[i]) + delay_us[i]))


@njit(cache=True)
def stable_order(keys):
    """The permutation that sorts ``keys`` (int64) stably: a counting sort over their span, or a merge sort
    where the span is over four times the count (plus 65,536)."""
    n = keys.shape[0]
    order = np.empty(n, np.int64)
    if n == 0:
        return order
    lo, hi = keys.min(), keys.max()
    span = hi - lo + 1
    if span > 4 * n + 65536:
        return np.argsort(keys, kind="mergesort")
    start = np.zeros(span + 1, np.int64)
    for i in range(n):
        start[keys[i] - lo + 1] += 1
    for j in range(span):
        start[j + 1] += start[j]
    for i in range(n):
        j = keys[i] - lo
        order[start[j]] = i
        start[j] += 1
    return order


@njit(cache=True)
def take(first, second, order, out):
    """out[j] = (first ++ second)[order[j]]: one field of the held and the new events, in the new order."""
    n_first = first.shape[0]
    for j in range(order.shape[0]):
        i = order[j]
        out[j] = first[i] if i < n_first else second[i - n_first]


@njit(cache=True)
def requesters(y, x, axis, per_row, axes, out):
    """The arbiter's requester of each event: y x per_row + x x axes (+ axis where ``axis`` is not empty)."""
    with_axis = axis.shape[0] > 0
    for i in range(out.shape[0]):
        r = np.int64(y[i]) * per_row + np.int64(x[i]) * axes
        out[i] = r + np.int64(axis[i]) if with_axis else r


@njit(cache=True)
def addresses(r, t, per_row, axes, y, x, axis, t_out):
    """Back from requesters ``r`` (and times ``t``) to the events' fields (``axis`` empty: none)."""
    with_axis = axis.shape[0] > 0
    for j in range(r.shape[0]):
        y[j] = r[j] // per_row
        x[j] = (r[j] % per_row) // axes
        if with_axis:
            axis[j] = r[j] % 2
        t_out[j] = t[j]
