"""Compiled loops of the long-step DVS prototype (issue 37, item 1; docs/long-steps.md, scheme A).

Each pixel walks its own time: from its state it takes the longest candidate leap (a whole number of
base steps h0) over which the probability of a grid crossing of the reference's DVS is bounded by eps
(a union bound over the grid with the exact transition's Gaussian law), else one base step. Every
advance is the photoreceptor's exact transition over the advance (the correlated pairs of
:mod:`gevsim.pixel._cascade`) followed by the reference's DVS rule with the advance as one step
(:func:`gevsim.events._kernels.brightness`, ported to one pixel). Pixels are independent: the caller
runs blocks of pixels on threads, each pixel through all frames of the chunk.

Candidate c has length ``cand[c]`` base steps: c < n_pow the powers of two below the frame's
``n_sub``, then c = n_pow + k whole groups of 2^k frames (k = 0 .. K).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gevsim.events._kernels import MAX_EVENTS_PER_STEP, _release
from gevsim.pixel._cascade import one_minus_exp, pair_coefficients, separate
from gevsim.pixel._fastmath import expf, logf
from gevsim.pixel._kernels import GOLDEN, normals_row, stream_key

#: The counter-based stream of the long-step advances: pixel p's three deviates of its a-th advance are
#: normal(pixel_bits(stream_key(key, p, STREAM_LONG), 3 a + m)), m = 0, 1, 2 (drawn NZ at a time).
STREAM_LONG = 37
NZ = 48
#: Columns of a pixel's cached coefficients per candidate: a, coupling, s1 (the photoreceptor pole's noise),
#: A1 (its share in the output), q (the rest of the output's noise, shot and read), var_y (the output noise's
#: variance), rho (the cascade's correlation over the candidate: how far the mean may fall back toward u).
NCOEF = 7
#: Columns of the global table per candidate: b2, eb2 (output pole), a_r, c_det, rs1, Ar (read noise: its
#: decay, its state's share in the output, its noise and that noise's share), rq (the read noise's own
#: part of the output's noise), var_y of the read noise.
NGLOB = 8
_TWO_PI = 2.0 * math.pi
#: Counters per pixel (``stats``): advances, leaps taken under the bound, base steps, leaps while held.
ADVANCES, BOUNDED, BASE, HELD = range(4)
#: Slots of the photoreceptor's scalars (``prs``): f_c per ampere, f_c limit, filter (1 or 0), beta,
#: shot_q, amp, h0.
FC_PER_A, FC_MAX, FILT, BETA, SHOT_Q, AMP, H0 = range(7)


@njit(cache=True)
def _light(itot, fc_per_a, fc_max, filt, beta, shot_q, amp):
    """(u, alpha, var) of a pixel's held total photocurrent: its log, the photoreceptor pole (rad/s, moved
    off the output pole as the reference moves it) and the pole's noise variance (ln^2)."""
    u = np.float64(logf(np.float32(itot)))
    fc = min(fc_per_a * itot, fc_max)
    alpha = separate(_TWO_PI * fc, beta)
    fc = alpha / _TWO_PI
    var = shot_q * fc / itot + amp / fc if filt > 0.0 else 0.0
    return u, alpha, var


@njit(cache=True)
def _coefficients(d, alpha, var, filt, beta, b2, eb2, read_q, read_var):
    """A pixel's photoreceptor pole's transition over d seconds (as :func:`gevsim.pixel._cascade.smooth_row`):
    the columns of :data:`NCOEF`. The output's noise c (x_n - q_n) of the pair is split into its regression
    on x_n (A1) and an independent rest, merged with the read noise's own independent rest (``read_q``)."""
    ea = one_minus_exp(alpha * d) * filt + (1.0 - filt)
    a = 1.0 - ea
    s1, r, s2, cc = pair_coefficients(var, alpha, beta, ea, eb2)
    rho = (beta * a - alpha * b2) / (beta - alpha) if filt > 0.0 else b2
    a1 = cc * (s1 - r)
    q2 = cc * cc * s2 * s2 + read_q * read_q
    return a, filt * beta / (beta - alpha) * (a - b2), s1, a1, math.sqrt(q2), a1 * a1 + q2 + read_var, rho


@njit(cache=True)
def _transition(u, x, y, r, co, gl, z1, zr, z3):
    """The photoreceptor's exact transition over a candidate (``co``: its :func:`_coefficients`, ``gl``: its
    row of the global table) from (x, y, r) (photoreceptor pole, output, read-noise state) with three
    independent standard normals: the pole's noise, the read noise's, the output's own rest."""
    e1 = x - u
    y_new = u + gl[0] * (y - u) + co[1] * e1 + gl[3] * r + co[3] * z1 + gl[5] * zr + co[4] * z3
    return u + co[0] * e1 + co[2] * z1, y_new, gl[2] * r + gl[4] * zr


@njit(cache=True)
def _fits(co, z, u, x, y, r, dist0, on, off, drift, g_r):
    """Whether a candidate keeps the bound: the mean of the output over the advance is u + e^(-beta t) (y - u)
    + G(t) (x - u) + G_r(t) r with coefficients >= 0 summing to the correlation rho(t), which falls from 1 to
    rho(h) (docs/long-steps.md), so it lies below u + max(y - u, x - u) (times rho(h) when negative) + g_r r+,
    and above the mirror image; ``dist0`` = offset - level turns it into the DVS distance, ``drift`` (the leak
    over the advance, doubled) can only raise it; both thresholds must then be z standard deviations of the
    output's noise over the advance away."""
    top = max(y - u, x - u)
    bottom = min(y - u, x - u)
    hi = u + (top if top >= 0.0 else co[6] * top) + g_r * max(r, 0.0) + dist0 + drift + 1e-6
    lo = u + (bottom if bottom <= 0.0 else co[6] * bottom) - g_r * max(-r, 0.0) + dist0 - 1e-6
    room = min(on - hi, off + lo)  # 1e-6: the float32 rounding of the sample
    return room > 0.0 and room * room >= z * z * co[5]


@njit(cache=True)
def _crossing(d, k, s, on, off):
    """The reference's next crossing from distance d at fraction s of a step with slope k: (fraction,
    polarity) or (inf, 0) for none."""
    if d >= on:
        return s, 1
    if d <= -off:
        return s, -1
    if k > 0.0:
        return s + (on - d) / k, 1
    if k < 0.0:
        return s + (-off - d) / k, -1
    return np.inf, 0


@njit(cache=True)
def _reset(reset_sigma, reset_key, p, count):
    """The distance on release from reset: :func:`gevsim.events._kernels._release` (compiled once here)."""
    return _release(reset_sigma, reset_key, p, count)


@njit(cache=True)
def _refill(skey, z, sp, idx):
    """z[i] = normal(pixel_bits(skey, i)): :func:`gevsim.pixel._kernels.normals_row` (compiled once here)."""
    normals_row(skey, z, sp, idx)


@njit(cache=True)
def _runs(current, p, run, most):
    """run[f] = how many frames from f (at most ``most``) hold pixel p's light ``current[f, p]`` unchanged."""
    F = current.shape[0]
    run[F - 1] = 1
    for f in range(F - 2, -1, -1):
        run[f] = min(run[f + 1] + 1, most) if current[f + 1, p] == current[f, p] else 1


@njit(cache=True)
def _at(fs, fe, j, n_sub):
    """The time of base step boundary j of a frame (fs, fe], as the driver's ``refine`` splits it."""
    return fe if j == n_sub else fs + (fe - fs) * (j / n_sub)


@njit(error_model="numpy", cache=True)
def _pixel(p, current, frame, pix, tables, dvs, state, key, bufs, n, cap, scratch, stats):
    """(Over 80 lines: one pixel's whole loop over its advances, its state in registers and no array passed
    to a call inside it: each such call cost ~130 ns in reference counts.) Pixel p through every frame of
    the chunk (``current`` (F, P): photocurrent per frame); returns the buffer fill, or -1 when the buffer is
    full. ``frame`` = (fs, fe, n_sub, frame0); ``pix`` = (gain, dark, offset, on, off, refractory); ``tables``
    = (cand, z, glob, n_pow, K, g_r, prs); ``dvs`` = (leak (ln/s), leak per exp(signal) (< 0: none), reset
    sigma, reset key, x, y); ``state`` = (v1, v2, rd, ref, v_prev, last_t, count, advances); ``bufs`` = (t, x,
    y, p); ``scratch`` = (cache, ok, runs, z, sp, idx).

    Each advance: choose (held in reset: the whole held steps; else the largest candidate that keeps the
    bound, by bisection: 2^k whole frames on their grid where the light is unchanged, the sizes within the
    frame, or a base step), the exact transition, then the reference's DVS rule over the advance as one
    step."""
    fs, fe, n_sub, frame0 = frame
    gain, dark, offset, on, off, refractory = pix
    cand, z, glob, n_pow, K, g_r, prs = tables
    leak, leak_light, reset_sigma, reset_key, px, py = dvs
    v1, v2, rd, ref_a, vp_a, lt_a, count_a, adv_a = state
    buf_t, buf_x, buf_y, buf_p = bufs
    cache, ok, runs, zb, sp, idx = scratch
    skey = stream_key(key, p, STREAM_LONG)
    adv = adv_a[p]
    zpos = NZ
    filt, beta, h0 = prs[FILT], prs[BETA], prs[H0]
    x, y, r = v1[p], v2[p], rd[p]
    ref, vp, lt, cnt = ref_a[p], vp_a[p], lt_a[p], count_a[p]
    _runs(current, p, runs, 1 << K)
    base = 0 if n_pow > 0 else n_pow
    cur = np.nan
    u, alpha, var = 0.0, 0.0, 0.0
    f, j = 0, 0
    while f < current.shape[0]:
        if current[f, p] != cur:  # the total photocurrent as the reference computes it
            cur = current[f, p]
            u, alpha, var = _light(cur * gain + dark, prs[FC_PER_A], prs[FC_MAX], filt, beta, prs[SHOT_Q], prs[AMP])
            for c in range(ok.shape[0]):
                ok[c] = False
        rate = leak + (leak_light * np.float64(expf(np.float32(vp))) if leak_light >= 0.0 else 0.0)
        ta = _at(fs[f], fe[f], j, n_sub)
        pick, m_pick, kind = base, 0, 0
        if refractory > 0.0 and lt >= ta - refractory:  # held in reset: the whole held steps in one leap
            for c in range(n_pow - 1, 0, -1):
                if j + cand[c] <= n_sub and lt + refractory - ta >= _at(fs[f], fe[f], j + cand[c], n_sub) - ta:
                    pick, kind = c, 2
                    break
        else:  # the largest candidate that keeps the bound: it holds for every shorter one, so bisect
            top = 0
            if j == 0:
                k = K
                while k > 0 and ((frame0 + f) & ((1 << k) - 1) != 0 or runs[f] < (1 << k)):
                    k -= 1
                top = n_pow + k
            else:
                top = n_pow - 1
                while top > 0 and j + cand[top] > n_sub:
                    top -= 1
            lo, hi = 0, top
            while lo < hi:
                c = (lo + hi + 1) // 2
                if not ok[c]:
                    co = _coefficients(cand[c] * h0, alpha, var, filt, beta, glob[c, 0], glob[c, 1], glob[c, 6],
                                       glob[c, 7])
                    for i in range(NCOEF):
                        cache[c, i] = co[i]
                    ok[c] = True
                co = (cache[c, 0], cache[c, 1], cache[c, 2], cache[c, 3], cache[c, 4], cache[c, 5], cache[c, 6])
                if _fits(co, z[c], u, x, y, r, offset - ref, on, off, 2.0 * rate * cand[c] * h0, g_r):
                    lo = c
                else:
                    hi = c - 1
            pick = lo
            m_pick = 1 << (lo - n_pow) if lo >= n_pow else 0
            kind = 1 if lo != base else 0
        c = pick
        if not ok[c]:
            co = _coefficients(cand[c] * h0, alpha, var, filt, beta, glob[c, 0], glob[c, 1], glob[c, 6], glob[c, 7])
            for i in range(NCOEF):
                cache[c, i] = co[i]
            ok[c] = True
        co = (cache[c, 0], cache[c, 1], cache[c, 2], cache[c, 3], cache[c, 4], cache[c, 5], cache[c, 6])
        gl = (glob[c, 0], glob[c, 1], glob[c, 2], glob[c, 3], glob[c, 4], glob[c, 5])
        if zpos + 3 > NZ:  # the next NZ deviates of the pixel's stream, from its advance count
            _refill(skey + np.uint64(3 * adv) * GOLDEN, zb, sp, idx)
            zpos = 0
        x, y, r = _transition(u, x, y, r, co, gl, np.float64(zb[zpos]), np.float64(zb[zpos + 1]),
                              np.float64(zb[zpos + 2]))
        zpos += 3
        adv += 1
        vs = np.float64(np.float32(np.float32(y) + offset))
        te = fe[f + m_pick - 1] if m_pick > 0 else _at(fs[f], fe[f], j + cand[c], n_sub)
        # the reference's DVS rule over the advance, as one step (gevsim.events._kernels.brightness)
        dt = te - ta
        us_end = np.int64(math.floor(te * 1e6 + 0.5))
        k = (vs - vp) + rate * dt
        d = vp - ref
        s = 0.0
        held = False
        if refractory > 0.0 and lt >= ta - refractory:
            ready = (lt + refractory - ta) / dt
            if ready >= 1.0:  # held through the advance: the level follows the signal
                held = True
            else:
                s = ready
                d = _reset(reset_sigma, reset_key, p, cnt)
        if not held:
            for _ in range(MAX_EVENTS_PER_STEP):
                cross, pol = _crossing(d, k, s, on, off)
                if cross > 1.0:
                    break
                if n >= cap:
                    return -1
                te_ev = ta + cross * dt
                buf_t[n] = min(np.int64(math.floor(te_ev * 1e6 + 0.5)), us_end)
                buf_x[n] = px
                buf_y[n] = py
                buf_p[n] = pol > 0
                n += 1
                cnt += 1
                lt = te_ev
                s = cross + refractory / dt if refractory > 0.0 else cross
                if s >= 1.0:  # held past the advance's end
                    d = 0.0
                    s = 1.0
                    break
                d = _reset(reset_sigma, reset_key, p, cnt)
            ref = vs - (d + k * (1.0 - s))
        else:
            ref = vs
        vp = vs
        stats[p, ADVANCES] += 1
        stats[p, BASE if kind == 0 else (BOUNDED if kind == 1 else HELD)] += 1
        if m_pick > 0:
            f += m_pick
        else:
            j += cand[c]
            if j == n_sub:
                f, j = f + 1, 0
    v1[p], v2[p], rd[p] = x, y, r
    ref_a[p], vp_a[p], lt_a[p], count_a[p], adv_a[p] = ref, vp, lt, cnt, adv
    return n


@njit(nogil=True, cache=True)
def run_pixels(lo, hi, current, frame, pixel_arrays, tables, dvs_arrays, dvs_scalars, state, key, bufs, n, cap,
               stats):
    """Pixels lo .. hi - 1 (``current`` (F, P): photocurrent per frame; a pixel reads its column, the cache
    lines of which serve the next pixels too), their events into ``bufs`` from n below cap; returns the fill
    (-1: full). ``pixel_arrays`` = (gain, dark, offset (float32), on, off);
    ``dvs_arrays`` = (leak, leak per exp(signal) (empty: none), x, y); ``dvs_scalars`` = (refractory, reset
    sigma, reset key)."""
    gain, dark, offset, th_on, th_off = pixel_arrays
    leak, leak_light, px, py = dvs_arrays
    refractory, reset_sigma, reset_key = dvs_scalars
    nc = tables[0].shape[0]
    scratch = (np.empty((nc, NCOEF)), np.zeros(nc, np.bool_), np.empty(current.shape[0], np.int64),
               np.empty(NZ, np.float32), np.empty(2 * NZ, np.float32), np.empty(NZ, np.int64))
    for p in range(lo, hi):
        ll = leak_light[p] if leak_light.shape[0] > 0 else -1.0
        n = _pixel(p, current, frame, (gain[p], dark[p], offset[p], th_on[p], th_off[p], refractory), tables,
                   (leak[p], ll, reset_sigma, reset_key, px[p], py[p]), state, key, bufs, n, cap, scratch, stats)
        if n < 0:
            return -1
    return n
