"""Compiled gradient kernel with crossings between the samples (:mod:`gevsim.events.bridge`; issue 37, item 1).

The same loop as :func:`gevsim.events._kernels.gradient` (rows, steps, axes; a vectorised pass finds the
comparators that change between the samples), plus the crossing rule. A comparator sees G = s (v(A) - v(B)) less
its offset (s = 1, or 1/2 with resolution compression); G's noise is the difference of two pixels' independent
noises, three components through the output pole (each pixel's photoreceptor pole at its own photocurrent, and the
read noise of both, which share a pole; :func:`gevsim.events._bridge.lane_law`). Without hysteresis the ternary
state is a function of G, so what the samples miss is:

- a comparator at the same state at both samples may have left it and come back (state 0: above +Theta or below
  -Theta; +-1: a dip to 0): N ~ Poisson(E) excursions, E Rice's expected crossings on the bridge;
- one that changes between 0 and +-1 crossed its level 2k + 1 times: N ~ Poisson(E - 1) more excursions.

Each excursion is two events of the side's polarity (Lehtonen et al.'s table gives 0 -> 1 and 1 -> 0 both +1, 0 ->
-1 and -1 -> 0 both -1): out at a time drawn from the side's crossing intensity, back at one drawn from the reverse
crossing intensity after it. E is capped at 2 + h max_k sqrt(a_k beta) / 2 pi (each end adds at most ~1 crossing,
and between them none come faster than the fastest component's own rate): the 16-node quadrature exceeds it only
for a sample within microns of its level (benchmarks/gradient_bridge.py). Measured there: within -3 % to +3 % of
5-us samples at 0.5-5 ms steps from 0.1 to 1000 chip lux (docs/bridge.md). The draws are keyed by (bridge key,
the step's end in microseconds, comparator, draw): the events depend on neither threads, rows nor chunks.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from gevsim.events._bridge import (
    _INV_SQ2PI,
    CELL,
    NODES,
    WEIGHT,
    XI,
    Z_SKIP,
    _exp,
    _mean_excess,
    lane_law,
    lanes,
    node_exps,
    node_terms,
)
from gevsim.events._bridge_dvs import FAR_SD, _uniform
from gevsim.events._kernels import CAP, FILL, RESUME_I, RESUME_T, START, STEP_END0, _crossing, _gradient_row
from gevsim.pixel._kernels import stream_key

#: Most excursions drawn per comparator, side and step.
MAX_EXCURSIONS = 64


@njit(cache=True, error_model="numpy", fastmath={"nnan", "ninf"})
def _shares(sx0, sx1, g0, g1, on, m, h, mom, fwd, rev, total):
    """For the m lanes whose side is ``on``: the node shares of the expected up-crossings (fwd) of the barrier
    B(t) = x0 + g0 + (x1 + g1 - x0 - g0) t / h by the bridge from sx0 to sx1 (any gaps), their sum (total), and
    the node shares of its down-crossings (rev), from :func:`gevsim.events._bridge.lanes`' moments."""
    for i in range(m):
        total[i] = 0.0
    for q in range(NODES):
        tq = XI[q] * h
        wq = WEIGHT[q] * h * _INV_SQ2PI
        for i in range(m):
            z, mu, dens = node_terms(sx0[i], sx1[i], g0[i], g1[i], tq, wq, h, mom, q, i)
            keep = (abs(z) <= Z_SKIP) & on[i]
            f = dens * _mean_excess(mu, mom[6, q, i]) if keep else 0.0
            fwd[q, i] = f
            rev[q, i] = dens * _mean_excess(-mu, mom[6, q, i]) if keep else 0.0
            total[i] += f


@njit(inline="always")
def _pick(shares, i, after, u):
    """A time (fraction of the step) drawn from lane i's node shares restricted to (after, 1]: the node whose
    share of that total u falls in, then uniform within its cell (after ``after``). 1.0 if nothing is left."""
    total = 0.0
    for q in range(NODES):
        lo, hi = CELL[q], CELL[q + 1]
        if hi > after:
            total += shares[q, i] * (hi - max(lo, after)) / (hi - lo)
    target = u * total
    acc = 0.0
    for q in range(NODES):
        lo, hi = CELL[q], CELL[q + 1]
        if hi <= after:
            continue
        lo = max(lo, after)
        part = shares[q, i] * (hi - lo) / (CELL[q + 1] - CELL[q])
        if part > 0.0 and (acc + part > target or q == NODES - 1):
            return lo + min(max((target - acc) / part, 0.0), 1.0) * (hi - lo)
        acc += part
    return 1.0


@njit(inline="always")
def _poisson(lam, u):
    """The Poisson(lam) count at uniform u, by inversion (at most MAX_EXCURSIONS)."""
    k = 0
    p = _exp(-lam)
    f = p
    while u > f and k < MAX_EXCURSIONS:
        k += 1
        p *= lam / k
        f += p
    return k


@njit(inline="always")
def _noise(v, mu, xprev0, tg, yy, xx):
    """A pixel's noise (signal less its noise-free value) at the samples before and after global step tg."""
    x1 = np.float64(v[tg, yy, xx]) - np.float64(mu[tg, yy, xx])
    x0 = xprev0[yy, xx] if tg == 0 else np.float64(v[tg - 1, yy, xx]) - np.float64(mu[tg - 1, yy, xx])
    return x0, x1


@njit(cache=True, error_model="numpy", fastmath={"nnan", "ninf"})
def _gather(v, mu, itot, xprev0, tg, axis, y, step_x, m, rc, state, t_new, g_old, g_new, theta, law, lv, la, lane,
            sx, gap, on, cross, pol, tmp):
    """The comparators of one row and axis at global step tg that the rule integrates, as lanes: their index,
    G's noise at both samples (sx[0]; sx[1] = -sx[0] for the down side), the two sides' gaps at both samples
    (gap[side, end]), whether each side is open (on), crosses between the samples (cross) and its polarity,
    and G's three noise components (lv, la). Returns the number of lanes."""
    H, W = v.shape[1], v.shape[2]
    n = 0
    for i in range(m):
        x = i * step_x
        s0 = state[x]
        s1 = t_new[i]
        if s0 * s1 == -1:  # from +1 to -1 or back: two levels, no extra
            continue
        if axis == 0:
            ya, xa = y, (x + 2 if x + 2 < W else x + 1) if rc else x + 1
        else:
            ya, xa = ((y + 2 if y + 2 < H else y + 1) if rc else y + 1), x
        scale = 0.5 if rc else 1.0
        a0, a1 = _noise(v, mu, xprev0, tg, ya, xa)
        b0, b1 = _noise(v, mu, xprev0, tg, y, x)
        x0 = scale * (a0 - b0)
        x1 = scale * (a1 - b1)
        th = theta[x]
        g0, g1 = g_old[x], g_new[i]
        # Up side (x rises through a level): state 0 at both or 0 -> 1 (+Theta); -1 at both or -1 -> 0 (-Theta).
        up_open = (s0 == 0 and s1 >= 0) or (s0 == -1)
        up_level = th if s0 == 0 else -th
        # Down side (x falls through a level): 0 at both or 0 -> -1 (-Theta); +1 at both or +1 -> 0 (+Theta).
        dn_open = (s0 == 0 and s1 <= 0) or (s0 == 1)
        dn_level = -th if s0 == 0 else th
        lane_law(law, np.float64(itot[tg, ya, xa]), tmp, tmp[2:], 0)
        lane_law(law, np.float64(itot[tg, y, x]), tmp, tmp[2:], 1)
        sd = math.sqrt(scale * scale * (tmp[0, 0] + tmp[0, 1] + 2.0 * law[5]))
        reach = 1.5 * max(abs(x0), abs(x1)) + FAR_SD * sd
        u0, u1 = up_level - g0, up_level - g1
        d0, d1 = g0 - dn_level, g1 - dn_level
        up_cross = up_open and s1 != s0
        dn_cross = dn_open and s1 != s0
        up_on = up_open and (up_cross or (u0 > 0.0 and u1 > 0.0 and min(u0 + x0, u1 + x1) < reach))
        dn_on = dn_open and (dn_cross or (d0 > 0.0 and d1 > 0.0 and min(d0 - x0, d1 - x1) < reach))
        if not (up_on or dn_on):
            continue
        lane[n] = i
        sx[0, n], sx[1, n], sx[2, n], sx[3, n] = x0, x1, -x0, -x1
        gap[0, n], gap[1, n], gap[2, n], gap[3, n] = u0, u1, d0, d1
        on[0, n], on[1, n] = up_on, dn_on
        cross[0, n], cross[1, n] = up_cross, dn_cross
        pol[0, n] = 1 if up_level > 0.0 else -1
        pol[1, n] = 1 if dn_level > 0.0 else -1
        lv[0, n], la[0, n] = scale * scale * tmp[0, 0], tmp[2, 0]
        lv[1, n], la[1, n] = scale * scale * tmp[0, 1], tmp[2, 1]
        lv[2, n], la[2, n] = scale * scale * 2.0 * law[5], law[6]
        n += 1
    return n


@njit(cache=True, error_model="numpy", fastmath={"nnan", "ninf"})
def _decide(n, h, beta, lv, la, sx, gap, on, cross, eb, c, cp, mom, fwd, rev, total, count, fire_key, cid0, step_x,
            lane):
    """Each lane's number of excursions per side (count[side, lane]) from the bridge's expected crossings, with
    keyed Poisson draws; returns twice their sum (the events they make)."""
    node_exps(beta, h, eb)
    lanes(lv, la, n, beta, h, eb, c, cp, mom, total[0])
    events = 0
    for side in range(2):
        _shares(sx[2 * side], sx[2 * side + 1], gap[2 * side], gap[2 * side + 1], on[side], n, h, mom, fwd[side],
                rev[side], total[side])
    for i in range(n):
        fastest = 0.0
        for k in range(lv.shape[0]):
            if lv[k, i] > 0.0:
                fastest = max(fastest, math.sqrt(la[k, i] * beta))
        cap = 2.0 + h * fastest / (2.0 * math.pi)
        for side in range(2):
            lam = total[side, i] - 1.0 if cross[side, i] else total[side, i]
            lam = min(max(lam, 0.0), cap) if on[side, i] else 0.0
            k = _poisson(lam, _uniform(fire_key, 2 * (cid0 + lane[i] * step_x) + side)) if lam > 0.0 else 0
            count[side, i] = k
            events += 2 * k
    return events


@njit(cache=True, error_model="numpy", fastmath={"nnan", "ninf"})
def _write(n, lane, count, fwd, rev, pol, axis, y, step_x, cid0, ta, dt, us_last, bridge_key, outs, sides, buf_t,
           buf_x, buf_y, buf_p, buf_axis, at):
    """The excursions' events into the buffers from ``at``; returns the new fill. Each lane's out-crossings (both
    sides) are drawn and sorted; each return is drawn after its out-crossing and before the next one (G cannot be
    above +Theta and below -Theta at once, and the events then decode to the comparator's state)."""
    for i in range(n):
        x = lane[i] * step_x
        cid = cid0 + x
        k = 0
        for side in range(2):
            for j in range(count[side, i]):
                u = _uniform(stream_key(bridge_key, us_last, 2 + 2 * (side * MAX_EXCURSIONS + j)), cid)
                s = _pick(fwd[side], i, 0.0, u)
                r = k
                while r > 0 and outs[r - 1] > s:
                    outs[r] = outs[r - 1]
                    sides[r] = sides[r - 1]
                    r -= 1
                outs[r] = s
                sides[r] = side
                k += 1
        for j in range(k):
            side = sides[j]
            u = _uniform(stream_key(bridge_key, us_last, 3 + 2 * (side * MAX_EXCURSIONS + j)), cid)
            back = _pick(rev[side], i, outs[j], u)
            if j + 1 < k:
                back = min(back, outs[j + 1])
            for s in (outs[j], back):
                buf_t[at] = min(np.int64(math.floor((ta + s * dt) * 1e6 + 0.5)), us_last)
                buf_x[at] = x
                buf_y[at] = y
                buf_p[at] = pol[side, i]
                buf_axis[at] = axis
                at += 1
    return at


@njit(cache=True, error_model="numpy", fastmath={"nnan", "ninf"})
def _changes(changed, idx, step_x, row_tern, row_g, row_theta, t_new, g_new, interpolate, ta, dt, us_last, table, axis,
             y, buf_t, buf_x, buf_y, buf_p, buf_axis, at):
    """The events of the comparators whose state changed between the samples (as the sampled kernel writes them)
    into the buffers from ``at``; their new states into ``row_tern``. Returns the new fill."""
    for q in range(changed):
        i = idx[q]
        x = i * step_x
        old = row_tern[x]
        new = t_new[i]
        s = _crossing(row_g[x], g_new[i], old, new, row_theta[x], 0.0) if interpolate else 1.0
        buf_t[at] = min(np.int64(math.floor((ta + s * dt) * 1e6 + 0.5)), us_last)
        buf_x[at] = x
        buf_y[at] = y
        buf_p[at] = table[old + 1, new + 1]
        buf_axis[at] = axis
        at += 1
        row_tern[x] = new
    return at


@njit(parallel=True, nogil=True, cache=True, error_model="numpy", fastmath={"nnan", "ninf"})
def gradient_bridged(v, mu, itot, xprev0, a, t_start, t_end, us_end, g_prev, tern, theta, offset, rc, interpolate,
                     table, law, bridge_key, buf_t, buf_x, buf_y, buf_p, buf_axis, region, order):
    """:func:`gevsim.events._kernels.gradient` (no hysteresis) with the crossing rule (module docstring) over
    global steps a .. a + len(t_end) - 1 of ``v``, ``mu`` (the noise-free signal) and ``itot`` (the total
    photocurrent over each step), all (T, H, W); ``xprev0`` (H, W): the noise at the sample before step 0;
    ``law``: :meth:`gevsim.pixel.noise.NoiseLaw.as_tuple`; ``bridge_key`` keys the rule's draws. A row and axis
    whose events do not all fit is left untouched and becomes the resume point, as there."""
    T = t_end.shape[0]
    H, W = v.shape[1], v.shape[2]
    beta = 2.0 * np.pi * law[4]
    empty = np.empty(0, v.dtype)
    for j in prange(order.shape[0]):
        y = order[j]
        t0 = region[y, RESUME_T]
        if t0 < T:
            g_new, t_new, idx = np.empty(W), np.empty(W, np.int8), np.empty(W, np.int64)
            lane, count = np.empty(W, np.int64), np.empty((2, W), np.int64)
            sx, gap, lv, la = np.empty((4, W)), np.empty((4, W)), np.empty((3, W)), np.empty((3, W))
            on, cross, pol = np.empty((2, W), np.bool_), np.empty((2, W), np.bool_), np.empty((2, W), np.int8)
            tmp, eb = np.empty((4, 2)), np.empty(NODES + 2)
            c, cp, mom = np.empty((NODES + 2, W)), np.empty((NODES + 2, W)), np.empty((7, NODES, W))
            fwd, rev, total = np.empty((2, NODES, W)), np.empty((2, NODES, W)), np.empty((2, W))
            outs, sides = np.empty(2 * MAX_EXCURSIONS), np.empty(2 * MAX_EXCURSIONS, np.int64)
            base, cap, n = region[y, START], region[y, CAP], region[y, FILL]
            stopped = False
            for t in range(t0, T):
                tg = a + t
                ta = t_start[t]
                dt = t_end[t] - ta
                fire_key = stream_key(bridge_key, us_end[t], 0)
                for axis in range(region[y, RESUME_I] if t == t0 else 0, 2):
                    if axis == 0:
                        step_x = 2 if rc else 1
                        m = W // 2 if rc else W - 1
                        changed = _gradient_row(v[tg, y], empty, step_x, m, theta[0, y], offset[0, y], tern[0, y],
                                                0.0, rc, g_new, t_new, idx)
                    else:
                        if y == H - 1 or (rc and y % 2 == 1):
                            continue
                        step_x = 1
                        m = W
                        there = (v[tg, y + 2] if y + 2 < H else v[tg, y + 1]) if rc else v[tg, y + 1]
                        changed = _gradient_row(v[tg, y], there, 1, m, theta[1, y], offset[1, y], tern[1, y], 0.0,
                                                rc, g_new, t_new, idx)
                    cid0 = (axis * H + y) * W
                    nl = _gather(v, mu, itot, xprev0, tg, axis, y, step_x, m, rc, tern[axis, y], t_new,
                                 g_prev[axis, y], g_new, theta[axis, y], law, lv, la, lane, sx, gap, on, cross, pol,
                                 tmp)
                    extra = _decide(nl, dt, beta, lv, la, sx, gap, on, cross, eb, c, cp, mom, fwd, rev, total, count,
                                    fire_key, cid0, step_x, lane) if nl else 0
                    if n + changed + extra > cap:  # nothing of this row and axis is written; resume here
                        stopped = True
                        region[y, RESUME_T] = t
                        region[y, RESUME_I] = axis
                        break
                    n = _changes(changed, idx, step_x, tern[axis, y], g_prev[axis, y], theta[axis, y], t_new, g_new,
                                 interpolate, ta, dt, us_end[t], table, axis, y, buf_t, buf_x, buf_y, buf_p, buf_axis,
                                 base + n) - base
                    if extra:
                        n = _write(nl, lane, count, fwd, rev, pol, axis, y, step_x, cid0, ta, dt, us_end[t],
                                   bridge_key, outs, sides, buf_t, buf_x, buf_y, buf_p, buf_axis, base + n) - base
                    row_g = g_prev[axis, y]
                    for i in range(m):
                        row_g[i * step_x] = g_new[i]
                if stopped:
                    break
                region[y, STEP_END0 + t] = n
            region[y, FILL] = n
            if not stopped:
                region[y, RESUME_T] = T
