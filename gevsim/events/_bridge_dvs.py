"""Compiled DVS kernel with crossings between the samples (:mod:`gevsim.events.bridge`; issue 37, item 1).

The same loop as :func:`gevsim.events._kernels.brightness` (blocks of pixels, a vectorised scan, the exact
per-pixel loop for the pixels that fire at a sample or are held), plus, each step, the crossing rule for the
pixels that stay quiet at both samples: each one's probability of an ON and an OFF crossing in between, given
both samples' noise (the signal minus its noise-free value) and its noise law at the step's photocurrent
(:func:`gevsim.events._bridge.lane_law`). A pixel that crosses fires at the drawn time and then runs the exact
loop from there (refractory period, reset noise, the rest of the step linear) with the others. At most one such
crossing per pixel and step.

The decision's uniforms are keyed by (the emulator's bridge key, the step's end in microseconds, the pixel):
the events depend on neither threads, blocks nor chunks.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from gevsim.events._bridge import NODES, lane_law, lanes, node_exps, probability, side, when
from gevsim.events._kernels import (
    BLOCK,
    CAP,
    FILL,
    RESUME_I,
    RESUME_T,
    START,
    STEP_END0,
    _compact,
    _dvs_commit,
    _dvs_scan,
    _pixel_step,
)
from gevsim.pixel._kernels import GOLDEN, mix64, stream_key

#: Sides further than this many noise standard deviations beyond the samples' excursion are not integrated
#: (as :data:`gevsim.events.bridge.FAR_SD`).
FAR_SD = 7.0


@njit(inline="always")
def _uniform(skey, p):
    """A uniform in [0, 1) for pixel p of a stream key (53 bits)."""
    return np.float64(mix64(skey + np.uint64(p) * GOLDEN) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True, error_model="numpy", fastmath={"nnan", "ninf"})
def _gather(first, hi, busy, v_t, mu_t, itot_t, v_prev, mu_prev, d0, d_end, th_on, th_off, law, lv, la, idx, x0,
            x1, g, far_sd):
    """The quiet pixels of [first, hi) (not busy) whose levels are within the noise's reach, as lanes: their
    scan slots idx, noise at both samples, gaps (g[0..3]: ON at start, end; OFF at start, end) and laws."""
    m = 0
    for i in range(hi - first):
        if busy[i]:
            continue
        p = first + i
        a = v_prev[p] - mu_prev[p]
        b = np.float64(v_t[i]) - np.float64(mu_t[i])
        on0, on1 = th_on[p] - d0[i], th_on[p] - d_end[i]
        off0, off1 = th_off[p] + d0[i], th_off[p] + d_end[i]
        lane_law(law, np.float64(itot_t[i]), lv, la, m)
        reach = 1.5 * max(abs(a), abs(b)) + far_sd * np.sqrt(lv[0, m] + lv[1, m])
        if min(on0 + a, on1 + b) < reach or min(off0 - a, off1 - b) < reach:
            idx[m] = i
            x0[m] = a
            x1[m] = b
            g[0, m] = on0
            g[1, m] = on1
            g[2, m] = off0
            g[3, m] = off1
            m += 1
    return m


@njit(cache=True, error_model="numpy", fastmath={"nnan", "ninf"})
def _decide(m, first, dt, beta, us_last, bridge_key, lv, la, x0, x1, sx0, sx1, g, eb, c, cp, mom, share, total,
            lane_idx, force_s, force_pol, busy):
    """For the m lanes of :func:`_gather`: each side's crossing probability over the step (ON: up through g[0..1],
    OFF: the negated noise up through g[2..3]), one keyed uniform per pixel to decide which side (if either)
    crosses and another to place it; a pixel that crosses is marked busy with its forced crossing."""
    node_exps(beta, dt, eb)
    lanes(lv, la, m, beta, dt, eb, c, cp, mom, total[0])
    side(x0, x1, g[0], g[1], m, dt, mom, share[0], total[0])
    for i in range(m):
        sx0[i] = -x0[i]
        sx1[i] = -x1[i]
    side(sx0, sx1, g[2], g[3], m, dt, mom, share[1], total[1])
    fire_key = stream_key(bridge_key, us_last, 0)
    time_key = stream_key(bridge_key, us_last, 1)
    for i in range(m):
        s_idx = lane_idx[i]
        p = first + s_idx
        p_on = probability(total[0, i])
        u = _uniform(fire_key, p)
        if u < p_on:
            force_s[s_idx] = when(share[0], i, total[0, i], _uniform(time_key, p))
            force_pol[s_idx] = 1
            busy[s_idx] = True
        elif u < p_on + probability(total[1, i]):
            force_s[s_idx] = when(share[1], i, total[1, i], _uniform(time_key, p))
            force_pol[s_idx] = -1
            busy[s_idx] = True


@njit(parallel=True, nogil=True, cache=True, error_model="numpy", fastmath={"nnan", "ninf"})
def brightness_bridged(v, mu, itot, t_start, t_end, us_end, ref, v_prev, mu_prev, last_t, count, th_on, th_off,
                       leak, leak_light, refractory, reset_sigma, key, bridge_key, law, px_x, px_y, buf_t, buf_x,
                       buf_y, buf_p, region, order):
    """:func:`gevsim.events._kernels.brightness` with the crossing rule (module docstring). ``mu`` (T, P): the
    noise-free signal at each sample; ``itot`` (T, P): the total photocurrent over each step (A); ``mu_prev``:
    the noise-free signal at the previous sample (updated like ``v_prev``); ``law``: the noise law
    (:meth:`gevsim.pixel.noise.NoiseLaw.as_tuple`); ``bridge_key``: keys the rule's uniforms."""
    T, P = v.shape
    beta = 2.0 * np.pi * law[4]
    for j in prange(order.shape[0]):
        b = order[j]
        t0 = region[b, RESUME_T]
        if t0 < T:
            lo = b * BLOCK
            hi = min(P, lo + BLOCK)
            base = region[b, START]
            cap = region[b, CAP]
            n = region[b, FILL]
            d0 = np.empty(BLOCK)
            slope = np.empty(BLOCK)
            d_end = np.empty(BLOCK)
            busy = np.empty(BLOCK, np.bool_)
            idx = np.empty(BLOCK, np.int64)
            lane_idx = np.empty(BLOCK, np.int64)
            force_s = np.full(BLOCK, -1.0)
            force_pol = np.zeros(BLOCK, np.int64)
            lv = np.empty((2, BLOCK))
            la = np.empty((2, BLOCK))
            x0 = np.empty(BLOCK)
            x1 = np.empty(BLOCK)
            sx0 = np.empty(BLOCK)
            sx1 = np.empty(BLOCK)
            g = np.empty((4, BLOCK))
            c = np.empty((NODES + 2, BLOCK))
            cp = np.empty((NODES + 2, BLOCK))
            mom = np.empty((7, NODES, BLOCK))
            share = np.empty((2, NODES, BLOCK))
            total = np.empty((2, BLOCK))
            eb = np.empty(NODES + 2)
            stopped = False
            for t in range(t0, T):
                ta = t_start[t]
                dt = t_end[t] - ta
                held_after = ta - refractory if refractory > 0.0 else np.inf
                first = lo + region[b, RESUME_I] if t == t0 else lo
                end = hi
                light = leak_light[first:hi] if leak_light.shape[0] else leak_light
                _dvs_scan(v[t, first:hi], ref[first:hi], v_prev[first:hi], leak[first:hi], light, th_on[first:hi],
                          th_off[first:hi], last_t[first:hi], held_after, dt, d0, slope, d_end, busy)
                for i in range(hi - first):
                    force_s[i] = -1.0
                m = _gather(first, hi, busy, v[t, first:hi], mu[t, first:hi], itot[t, first:hi], v_prev, mu_prev,
                            d0, d_end, th_on, th_off, law, lv, la, lane_idx, x0, x1, g, FAR_SD)
                if m:
                    _decide(m, first, dt, beta, us_end[t], bridge_key, lv, la, x0, x1, sx0, sx1, g, eb, c, cp, mom,
                            share, total, lane_idx, force_s, force_pol, busy)
                for q in range(_compact(busy, hi - first, idx)):
                    i = idx[q]
                    p = first + i
                    n, stopped = _pixel_step(i, p, force_s[i], force_pol[i], d0, slope, d_end, last_t, count, th_on,
                                             th_off, held_after, ta, dt, refractory, reset_sigma, key, px_x, px_y,
                                             us_end[t], buf_t, buf_x, buf_y, buf_p, base, n, cap)
                    if stopped:  # this pixel's step and the rest are redone on resumption
                        region[b, RESUME_T] = t
                        region[b, RESUME_I] = p - lo
                        end = p
                        break
                _dvs_commit(v[t, first:end], ref[first:end], v_prev[first:end], d_end)
                for p in range(first, end):
                    mu_prev[p] = mu[t, p]
                if stopped:
                    break
                region[b, STEP_END0 + t] = n
            region[b, FILL] = n
            if not stopped:
                region[b, RESUME_T] = T
