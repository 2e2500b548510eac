"""Compiled inner loops of the event emulators (numba).

Both kernels walk a chunk of T steps of a signal sampled at the step ends and
linear in between. Pixels are split into fixed blocks (rows for gradient
events), so results do not depend on the number of threads. Block b writes its
events, in emission order (step by step), into its own region of flat buffers
(``region[b]``: start, capacity, fill) and records its fill after every step.
A block whose region is full stops at a step boundary of one pixel (DVS) or one
row and axis (gradient), before touching that unit's state, and records where
to resume; the caller grows the regions and calls the kernel again, which goes
on from there. No finished work is ever redone. :mod:`gevsim.events._collect`
then gathers the regions into time order. Blocks are taken in the order ``order``
(interleaved, so that each thread's share mixes parts of the image; results do
not depend on it).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from gevsim.pixel._fastmath import expf
from gevsim.pixel._kernels import normal, pixel_bits, stream_key

BLOCK = 1024
MAX_EVENTS_PER_STEP = 4096  # per pixel; guards against a vanishing threshold

#: Columns of the ``region`` table (one row per block): where the block's region of the flat
#: event buffers starts, its capacity, how many events it holds, the step and the pixel (DVS,
#: counted from the block's first) or axis (gradient) to resume from (RESUME_T = T: finished),
#: then for each step t of the chunk the fill after step t (so step t's events are
#: [end(t - 1), end(t)) of the region).
START, CAP, FILL, RESUME_T, RESUME_I, STEP_END0 = range(6)

#: Gradient event from (T_prev, T), rows T_prev = -1, 0, 1, columns T = -1, 0, 1 (Lehtonen et al., Table 1).
EVENT_TABLE = np.array([[0, -1, 1], [-1, 0, 1], [-1, 1, 0]], dtype=np.int8)


@njit(inline="never", error_model="numpy", fastmath={"nnan", "ninf"}, cache=True)
def _dvs_scan(v_row, ref, v_prev, leak, leak_light, th_on, th_off, last_t, held_after, dt, d0, slope, d_end, busy):
    """Branch-free (vectorised) pass over a run of pixels (all arguments sliced to it) for
    one step: the distance d0 = signal - level at the step start, its slope over the step
    (signal change plus leak: ``leak`` + ``leak_light`` x the photocurrent exp(signal) at the step
    start, when ``leak_light`` is not empty),
    the distance at the step end if no event fires, and whether the pixel needs the exact
    loop: its distance reaches a threshold within 1e-9 relative (a superset of the pixels
    that fire), or it is still held in reset (refractory) at the step start
    (``last_t > held_after``). Returns how many need it. (Slices rather than offsets: LLVM
    vectorises this 4x better.)"""
    m = 0
    light = leak_light.shape[0] > 0
    for i in range(v_row.shape[0]):
        v0 = v_prev[i]
        rate = leak[i]
        if light:
            rate += leak_light[i] * np.float64(expf(np.float32(v0)))
        k = (np.float64(v_row[i]) - v0) + rate * dt
        d = v0 - ref[i]
        e = d + k * 1.0
        on = th_on[i]
        off = th_off[i]
        tol = 1e-9 * (abs(d) + abs(k) + on + off)
        f = (d >= on - tol) | (d <= tol - off) | (e >= on - tol) | (e <= tol - off) | (last_t[i] >= held_after)
        d0[i] = d
        slope[i] = k
        d_end[i] = e
        busy[i] = f
        m += f
    return m


@njit(inline="always")
def _compact(busy, n, idx):
    """Indices of the set flags among busy[:n], branch-free (no mispredicted jumps over
    the pixels that stay quiet)."""
    m = 0
    for i in range(n):
        idx[m] = i
        m += busy[i]
    return m


@njit(inline="never", error_model="numpy", fastmath={"nnan", "ninf"}, cache=True)
def _dvs_commit(v_row, ref, v_prev, d_end):
    """New levels of a run of pixels (arguments sliced to it) from their distances at the step end."""
    for i in range(v_row.shape[0]):
        v1 = np.float64(v_row[i])
        ref[i] = v1 - d_end[i]
        v_prev[i] = v1


@njit(inline="always")
def _release(reset_sigma, key, p, count):
    """The distance right after a pixel's change amplifier leaves reset (it is 0 while held): minus
    the reset (kTC, charge injection) noise of that release, a normal deviate keyed by (key, pixel,
    its event count), so that it depends on neither chunks nor threads."""
    if reset_sigma > 0.0:
        return -reset_sigma * np.float64(normal(pixel_bits(stream_key(key, count, 0), p)))
    return 0.0


@njit(inline="always")
def _pixel_step(i, p, force_s, force_pol, d0, slope, d_end, last_t, count, th_on, th_off, held_after, ta, dt,
                refractory, reset_sigma, key, px_x, px_y, us_last, buf_t, buf_x, buf_y, buf_p, base, n, cap):
    """The exact crossing loop of one pixel (``p``, scan slot ``i``) over one step: its events into the
    buffers from ``n``, its distance at the step end into d_end[i], its last event time and count. A crossing
    at ``force_s`` (fraction of the step, >= 0) of polarity ``force_pol`` comes first, if given (a crossing
    between the samples: :mod:`gevsim.events._bridge_dvs`). Returns (n, stopped): stopped when the events
    do not fit (nothing of this pixel's step is kept then: n is the value on entry). After a forced crossing the
    signal runs straight from the level to the step's end sample (its slope changes; otherwise it never does)."""
    n_pixel = n
    lt = last_t[p]
    c = count[p]
    k = slope[i]
    d = d0[i]
    s = 0.0
    m = 0
    on, off = th_on[p], th_off[p]
    if lt >= held_after:  # held in reset since an earlier step
        ready = (lt + refractory - ta) / dt
        if ready >= 1.0:
            d_end[i] = 0.0  # still held at the step end: the level is the signal
            return n, False
        s = ready
        d = _release(reset_sigma, key, p, c)
    k_after = k
    while m < MAX_EVENTS_PER_STEP:
        if force_s >= 0.0:  # the signal was at the level then: from there it runs straight to the step's end
            cross, pol = force_s, force_pol
            k_after = (d + k - (on if pol > 0 else -off)) / max(1.0 - force_s, 1e-12)
            force_s = -1.0
        elif d >= on:
            cross, pol = s, 1
        elif d <= -off:
            cross, pol = s, -1
        elif k > 0.0:
            cross, pol = s + (on - d) / k, 1
        elif k < 0.0:
            cross, pol = s + (-off - d) / k, -1
        else:
            break
        if cross > 1.0:
            break
        te = ta + cross * dt
        if n == cap:
            return n_pixel, True
        buf_t[base + n] = min(np.int64(math.floor(te * 1e6 + 0.5)), us_last)
        buf_x[base + n] = px_x[p]
        buf_y[base + n] = px_y[p]
        buf_p[base + n] = pol > 0
        n += 1
        c += 1
        lt = te
        m += 1
        k = k_after
        s = cross + refractory / dt if refractory > 0.0 else cross
        if s >= 1.0:  # held in reset past the step end
            d = 0.0
            s = 1.0
            break
        d = _release(reset_sigma, key, p, c)
    d_end[i] = d + k * (1.0 - s)
    last_t[p] = lt
    count[p] = c
    return n, False


@njit(parallel=True, nogil=True, cache=True)
def brightness(v, t_start, t_end, us_end, ref, v_prev, last_t, count, th_on, th_off, leak, leak_light, refractory,
               reset_sigma, key, px_x, px_y, buf_t, buf_x, buf_y, buf_p, region, order):
    """(Over 80 lines: one compiled loop over blocks and steps, so that a block's state stays in cache.)
    DVS: per pixel a memorised level ``ref``; an ON (OFF) event when the signal
    rises (falls) by th_on (th_off) from it, at the linearly interpolated crossing
    time. The change amplifier is then held in reset for ``refractory`` seconds: the
    level follows the signal and changes during that time are forgotten (Lichtsteiner,
    Posch & Delbruck 2008; so a ramp of slope k gives events refractory + theta / k apart).
    On release the level takes a reset error of sigma ``reset_sigma`` (ln). ``leak`` (ln/s)
    lowers the level over time, producing leak (ON) events; ``leak_light`` (ln/s per A; empty: none)
    adds leak in proportion to the photocurrent exp(v). ``count`` (P,) counts each
    pixel's events (it keys the reset noise).

    Per block and step, a vectorised scan finds the pixels that may fire or are held; the
    exact crossing loop runs for those only, in pixel order. Block b (pixels b * BLOCK ...)
    writes its events into its own region of the flat buffers from its resume point (see
    :data:`START`); a pixel whose events of a step do not fit is left untouched (as are
    the pixels after it) and becomes the block's resume point."""
    T, P = v.shape
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
            stopped = False
            for t in range(t0, T):
                ta = t_start[t]
                dt = t_end[t] - ta
                held_after = ta - refractory if refractory > 0.0 else np.inf
                first = lo + region[b, RESUME_I] if t == t0 else lo
                end = hi
                light = leak_light[first:hi] if leak_light.shape[0] else leak_light
                if _dvs_scan(v[t, first:hi], ref[first:hi], v_prev[first:hi], leak[first:hi], light, th_on[first:hi],
                             th_off[first:hi], last_t[first:hi], held_after, dt, d0, slope, d_end, busy):
                    for q in range(_compact(busy, hi - first, idx)):
                        i = idx[q]
                        p = first + i
                        n, stopped = _pixel_step(i, p, -1.0, 0, d0, slope, d_end, last_t, count, th_on, th_off,
                                                 held_after, ta, dt, refractory, reset_sigma, key, px_x, px_y,
                                                 us_end[t], buf_t, buf_x, buf_y, buf_p, base, n, cap)
                        if stopped:  # this pixel's step and the rest are redone on resumption
                            region[b, RESUME_T] = t
                            region[b, RESUME_I] = p - lo
                            end = p
                            break
                _dvs_commit(v[t, first:end], ref[first:end], v_prev[first:end], d_end)
                if stopped:
                    break
                region[b, STEP_END0 + t] = n
            region[b, FILL] = n
            if not stopped:
                region[b, RESUME_T] = T


@njit(inline="always")
def _crossing(g0, g1, t_prev, t_new, theta, hysteresis):
    """Fraction of the step at which g crossed the threshold that makes t_new."""
    if t_new == 1:
        level = theta
    elif t_new == -1:
        level = -theta
    elif t_prev == 1:
        level = theta - hysteresis
    else:
        level = hysteresis - theta
    if g1 == g0:
        return 1.0
    s = (level - g0) / (g1 - g0)
    return min(max(s, 0.0), 1.0)


@njit(inline="never", error_model="numpy", fastmath={"nnan", "ninf"}, cache=True)
def _gradient_row(here, there, step_x, n, theta, offset, tern, hysteresis, rc, g_new, t_new, idx):
    """Branch-free (vectorised) pass over one row of comparators of one axis: the new
    gradient and ternary state of comparator i at pixel i * step_x, where the
    neighbour values are ``there`` (same pixel, next row) for G_Y or ``here`` shifted
    by one for G_X, less the comparator's input offset; then the list ``idx`` of the
    comparators that change state (in order, branch-free). Returns its length."""
    for i in range(n):
        x = i * step_x
        if there.shape[0] == 0:  # X axis: neighbours in the same row
            g = np.float64(here[x + 1]) - np.float64(here[x])
            g2 = (np.float64(here[x + 2]) - np.float64(here[x + 1])) if x + 2 < here.shape[0] else 0.0
        else:  # Y axis: ``there`` is the next row (with RC the one after it, whose difference is halved)
            g = np.float64(there[x]) - np.float64(here[x])
            g2 = 0.0
        g = (0.5 * (g + g2) if rc else g) - offset[x]
        th = theta[x]
        old = tern[x]
        up = (g >= th) | ((old == 1) & (g >= th - hysteresis))
        down = (g <= -th) | ((old == -1) & (g <= hysteresis - th))
        g_new[i] = g
        t_new[i] = np.int8(1) if up else (np.int8(-1) if down else np.int8(0))
    changed = 0
    for i in range(n):
        idx[changed] = i
        changed += t_new[i] != tern[i * step_x]
    return changed


@njit(parallel=True, nogil=True, cache=True)
def gradient(v, t_start, t_end, us_end, g_prev, tern, theta, offset, hysteresis, rc, interpolate, table,
             buf_t, buf_x, buf_y, buf_p, buf_axis, region, order):
    """(Over 80 lines: one compiled loop over rows and steps, so that a row's state stays in cache.)
    Gradient events (Lehtonen et al.): for each comparator (axis a, pixel y, x)
    G_X = v[y, x+1] - v[y, x], G_Y = v[y+1, x] - v[y, x] (with resolution
    compression ``rc`` the mean over the pair starting at even x resp. even y,
    one comparator per pair); ternary state T = sgn(G) if |G| >= theta else 0;
    an event ``table[T_prev + 1, T + 1]`` whenever T changes. G is taken less the
    comparator's input offset ``offset``. g_prev, tern, theta and offset are (2, H, W);
    v is (T, H, W). A vectorised pass finds the comparators
    that change; events are then written for those only.

    Row y is block y: it writes into its own region of the flat buffers, from its resume
    point (step, axis); a row of one axis whose events do not all fit is left untouched
    and becomes the resume point."""
    T, H, W = v.shape
    empty = np.empty(0, v.dtype)
    for j in prange(order.shape[0]):
        y = order[j]
        t0 = region[y, RESUME_T]
        if t0 < T:
            g_new = np.empty(W)
            t_new = np.empty(W, np.int8)
            idx = np.empty(W, np.int64)
            base = region[y, START]
            cap = region[y, CAP]
            n = region[y, FILL]
            stopped = False
            for t in range(t0, T):
                ta = t_start[t]
                dt = t_end[t] - ta
                for axis in range(region[y, RESUME_I] if t == t0 else 0, 2):
                    if axis == 0:
                        step_x = 2 if rc else 1
                        m = W // 2 if rc else W - 1
                        if rc:
                            changed = _gradient_row(v[t, y], empty, 2, m, theta[0, y], offset[0, y], tern[0, y],
                                                    hysteresis, True, g_new, t_new, idx)
                        else:
                            changed = _gradient_row(v[t, y], empty, 1, m, theta[0, y], offset[0, y], tern[0, y],
                                                    hysteresis, False, g_new, t_new, idx)
                    else:
                        if y == H - 1 or (rc and y % 2 == 1):
                            continue
                        step_x = 1
                        m = W
                        if rc:
                            # Mean of G_Y(y) and G_Y(y + 1) = (v[y + 2] - v[y]) / 2 (G_Y of the last row is 0).
                            there = v[t, y + 2] if y + 2 < H else v[t, y + 1]
                            changed = _gradient_row(v[t, y], there, 1, m, theta[1, y], offset[1, y], tern[1, y],
                                                    hysteresis, True, g_new, t_new, idx)
                        else:
                            changed = _gradient_row(v[t, y], v[t, y + 1], 1, m, theta[1, y], offset[1, y], tern[1, y],
                                                    hysteresis, False, g_new, t_new, idx)
                    if n + changed > cap:  # nothing of this row and axis is written; resume here
                        stopped = True
                        region[y, RESUME_T] = t
                        region[y, RESUME_I] = axis
                        break
                    row_tern = tern[axis, y]
                    row_g = g_prev[axis, y]
                    row_theta = theta[axis, y]
                    for q in range(changed):
                        i = idx[q]
                        x = i * step_x
                        old = row_tern[x]
                        new = t_new[i]
                        s = _crossing(row_g[x], g_new[i], old, new, row_theta[x], hysteresis) if interpolate else 1.0
                        te = ta + s * dt
                        buf_t[base + n] = min(np.int64(math.floor(te * 1e6 + 0.5)), us_end[t])
                        buf_x[base + n] = x
                        buf_y[base + n] = y
                        buf_p[base + n] = table[old + 1, new + 1]
                        buf_axis[base + n] = axis
                        n += 1
                        row_tern[x] = new
                    for i in range(m):
                        row_g[i * step_x] = g_new[i]
                if stopped:
                    break
                region[y, STEP_END0 + t] = n
            region[y, FILL] = n
            if not stopped:
                region[y, RESUME_T] = T


@njit(cache=True)
def apply_gradient_events(state, axis, y, x, p, table):
    """Apply events in order to a ternary state (2, H, W): the inverse of ``table``."""
    for i in range(len(p)):
        a, yy, xx = axis[i], y[i], x[i]
        row = state[a, yy, xx] + 1
        for col in range(3):
            if table[row, col] == p[i]:
                state[a, yy, xx] = col - 1
                break
    return state
