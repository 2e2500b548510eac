"""Compiled inner loops of the event emulators (numba).

Both kernels walk a chunk of T steps of a signal sampled at the step ends and
linear in between, and write events into per-block buffers: block b owns
``buf_*[b, :cap]``. Pixels are split into fixed blocks (rows for gradient
events), so results do not depend on the number of threads. A full buffer
sets ``count[b] = cap + 1``; the caller then retries the chunk with larger
buffers from a copy of the state.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

BLOCK = 1024
MAX_EVENTS_PER_STEP = 4096  # per pixel; guards against a vanishing threshold

#: Gradient event from (T_prev, T), rows T_prev = -1, 0, 1, columns T = -1, 0, 1 (Lehtonen et al., Table 1).
EVENT_TABLE = np.array([[0, -1, 1], [-1, 0, 1], [-1, 1, 0]], dtype=np.int8)


@njit(inline="always")
def _push(b, cap, count, buf_t, buf_step, buf_pix, buf_p, buf_axis, t_us, step, pix, p, axis):
    n = count[b]
    if n < cap:
        buf_t[b, n] = t_us
        buf_step[b, n] = step
        buf_pix[b, n] = pix
        buf_p[b, n] = p
        buf_axis[b, n] = axis
    count[b] = min(n + 1, cap + 1)


@njit(parallel=True, cache=True)
def brightness(v, t_start, t_end, ref, v_prev, last_t, th_on, th_off, leak, refractory,
               buf_t, buf_step, buf_pix, buf_p, buf_axis, count):
    """DVS: per pixel a memorised level ``ref``; an ON (OFF) event when the signal
    rises (falls) by th_on (th_off) from it, at the linearly interpolated crossing
    time, not sooner than ``refractory`` after the pixel's previous event; the
    level is then reset to the signal. ``leak`` (ln/s) lowers the level over
    time, producing leak (ON) events."""
    T, P = v.shape
    cap = buf_t.shape[1]
    nblocks = (P + BLOCK - 1) // BLOCK
    for b in prange(nblocks):
        lo = b * BLOCK
        hi = min(P, lo + BLOCK)
        for t in range(T):
            ta = t_start[t]
            dt = t_end[t] - ta
            for p in range(lo, hi):
                v0 = v_prev[p]
                v1 = np.float64(v[t, p])
                k = (v1 - v0) + leak[p] * dt  # slope of d = signal - level over the step (per unit s)
                d = v0 - ref[p]
                s = 0.0
                n = 0
                while n < MAX_EVENTS_PER_STEP:
                    on, off = th_on[p], th_off[p]
                    if d >= on:
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
                    se = cross
                    if refractory > 0.0:
                        ready = (last_t[p] + refractory - ta) / dt
                        if ready > se:
                            # Refractory: fire when it ends, if still beyond the threshold.
                            se = ready
                            if se > 1.0:
                                break
                            de = d + k * (se - s)
                            if (pol == 1 and de < on) or (pol == -1 and de > -off):
                                # Fell back inside the thresholds while refractory: no event;
                                # look on from the end of the refractory period.
                                d = de
                                s = se
                                n += 1
                                continue
                    te = ta + se * dt
                    _push(b, cap, count, buf_t, buf_step, buf_pix, buf_p, buf_axis,
                          np.int64(math.floor(te * 1e6 + 0.5)), t, p, pol, 0)
                    last_t[p] = te
                    d = 0.0
                    s = se
                    n += 1
                d += k * (1.0 - s)
                ref[p] = v1 - d
                v_prev[p] = v1
    return count


@njit(inline="always")
def _ternary(g, theta):
    if g >= theta:
        return 1
    if g <= -theta:
        return -1
    return 0


@njit(inline="always")
def _ternary_hysteresis(g, theta, t_old, hysteresis):
    """Ternary state with comparator hysteresis: a +-1 state holds until |G| drops
    below theta - hysteresis (0 hysteresis: the paper's definition)."""
    if t_old == 1 and g >= theta - hysteresis:
        return 1
    if t_old == -1 and g <= hysteresis - theta:
        return -1
    return _ternary(g, theta)


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
def _gradient_row(here, there, step_x, n, theta, g_prev, tern, hysteresis, rc, g_new, t_new):
    """Branch-free (vectorised) pass over one row of comparators of one axis: the new
    gradient and ternary state of comparator i at pixel i * step_x, where the
    neighbour values are ``there`` (same pixel, next row) for G_Y or ``here`` shifted
    by one for G_X. Returns how many comparators changed state."""
    changed = 0
    for i in range(n):
        x = i * step_x
        if there.shape[0] == 0:  # X axis: neighbours in the same row
            g = np.float64(here[x + 1]) - np.float64(here[x])
            g2 = (np.float64(here[x + 2]) - np.float64(here[x + 1])) if x + 2 < here.shape[0] else 0.0
        else:  # Y axis: ``there`` is the next row (with RC the one after it, whose difference is halved)
            g = np.float64(there[x]) - np.float64(here[x])
            g2 = 0.0
        g = 0.5 * (g + g2) if rc else g
        th = theta[x]
        old = tern[x]
        up = (g >= th) or (old == 1 and g >= th - hysteresis)
        down = (g <= -th) or (old == -1 and g <= hysteresis - th)
        new = np.int8(1) if up else (np.int8(-1) if down else np.int8(0))
        g_new[i] = g
        t_new[i] = new
        changed += new != old
    return changed


@njit(parallel=True, cache=True)
def gradient(v, t_start, t_end, g_prev, tern, theta, hysteresis, rc, interpolate, table,
             buf_t, buf_step, buf_pix, buf_p, buf_axis, count):
    """Gradient events (Lehtonen et al.): for each comparator (axis a, pixel y, x)
    G_X = v[y, x+1] - v[y, x], G_Y = v[y+1, x] - v[y, x] (with resolution
    compression ``rc`` the mean over the pair starting at even x resp. even y,
    one comparator per pair); ternary state T = sgn(G) if |G| >= theta else 0;
    an event ``table[T_prev + 1, T + 1]`` whenever T changes. g_prev, tern and
    theta are (2, H, W); v is (T, H, W). A vectorised pass finds the comparators
    that change; events are then written for those only."""
    T, H, W = v.shape
    cap = buf_t.shape[1]
    empty = np.empty(0, v.dtype)
    for y in prange(H):
        g_new = np.empty(W)
        t_new = np.empty(W, np.int8)
        for t in range(T):
            ta = t_start[t]
            dt = t_end[t] - ta
            for axis in range(2):
                if axis == 0:
                    step_x = 2 if rc else 1
                    n = W // 2 if rc else W - 1
                    if rc:
                        changed = _gradient_row(v[t, y], empty, 2, n, theta[0, y], g_prev[0, y], tern[0, y],
                                                hysteresis, True, g_new, t_new)
                    else:
                        changed = _gradient_row(v[t, y], empty, 1, n, theta[0, y], g_prev[0, y], tern[0, y],
                                                hysteresis, False, g_new, t_new)
                else:
                    if y == H - 1 or (rc and y % 2 == 1):
                        continue
                    step_x = 1
                    n = W
                    if rc:
                        # Mean of G_Y(y) and G_Y(y + 1) = (v[y + 2] - v[y]) / 2 (G_Y of the last row is 0).
                        there = v[t, y + 2] if y + 2 < H else v[t, y + 1]
                        changed = _gradient_row(v[t, y], there, 1, n, theta[1, y], g_prev[1, y], tern[1, y],
                                                hysteresis, True, g_new, t_new)
                    else:
                        changed = _gradient_row(v[t, y], v[t, y + 1], 1, n, theta[1, y], g_prev[1, y],
                                                tern[1, y], hysteresis, False, g_new, t_new)
                if changed:
                    for i in range(n):
                        x = i * step_x
                        old = tern[axis, y, x]
                        new = t_new[i]
                        if new != old:
                            th = theta[axis, y, x]
                            s = _crossing(g_prev[axis, y, x], g_new[i], old, new, th, hysteresis) \
                                if interpolate else 1.0
                            te = ta + s * dt
                            _push(y, cap, count, buf_t, buf_step, buf_pix, buf_p, buf_axis,
                                  np.int64(math.floor(te * 1e6 + 0.5)), t, y * W + x, table[old + 1, new + 1], axis)
                            tern[axis, y, x] = new
                for i in range(n):
                    g_prev[axis, y, i * step_x] = g_new[i]
    return count


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


MAX_SORT_KEYS = 1 << 26


@njit(cache=True)
def collect(buf_t, buf_step, buf_pix, buf_p, buf_axis, count, n_steps, width, x, y, t, p, axis):
    """Gather the block buffers into time order: a stable counting sort on
    (timestamp, step) over the blocks taken in order, so ties keep block and
    emission order. Timestamps grow with the step, so this order does not depend
    on how a sequence is cut into chunks. Writes x, y, t, p, axis (length sum(count))."""
    nblocks = count.shape[0]
    tmin = np.int64(0)
    tmax = np.int64(0)
    first = True
    for b in range(nblocks):
        for i in range(count[b]):
            v = buf_t[b, i]
            if first or v < tmin:
                tmin = v
            if first or v > tmax:
                tmax = v
            first = False
    if first:
        return True
    nkeys = (tmax - tmin + 1) * n_steps
    if nkeys > MAX_SORT_KEYS:
        return False  # the caller sorts instead
    hist = np.zeros(nkeys + 1, np.int64)
    for b in range(nblocks):
        for i in range(count[b]):
            hist[(buf_t[b, i] - tmin) * n_steps + buf_step[b, i] + 1] += 1
    for k in range(nkeys):
        hist[k + 1] += hist[k]
    for b in range(nblocks):
        for i in range(count[b]):
            key = (buf_t[b, i] - tmin) * n_steps + buf_step[b, i]
            j = hist[key]
            hist[key] = j + 1
            pix = buf_pix[b, i]
            x[j] = pix % width
            y[j] = pix // width
            t[j] = buf_t[b, i]
            p[j] = buf_p[b, i]
            axis[j] = buf_axis[b, i]
    return True
