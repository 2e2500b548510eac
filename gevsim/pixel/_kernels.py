"""Compiled inner loops of the photoreceptor and its noise (numba).

Noise comes from a counter-based generator: a 64-bit integer hash of
(key, global step, stream, pixel) whose top 32 bits are mapped to a standard normal by
inversion (Acklam's rational approximation of the inverse normal CDF). The loops are
written branch-free with vectorisable log and exp (:mod:`gevsim.pixel._fastmath`) so
that they run on SIMD vectors. A draw depends only on its counter, so results are
identical for any chunking of time and any number of threads, bit for bit.

Why 64 bits: the former generator hashed a 32-bit key per (step, stream, block) XOR the
pixel; two steps whose keys differ only in the low 10 bits hash the same 1024 inputs, so
they draw the same noise field, shuffled across the block's pixels. With 2^22 such classes,
1 s of 10 us steps (10^5 steps) at 346x260 held ~26,000 such pairs. Here a step's stream key
has 64 bits and pixel i of it hashes ``key + i * GOLDEN`` (a Weyl sequence, as in SplitMix64):
two steps share inputs only if their keys differ by less than the pixel count times GOLDEN
modulo 2^64, about 2^-45 per pair of steps at 346x260.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from gevsim._portable import exp_scalar, expm1_scalar
from gevsim.pixel._cascade import read_coefficients, smooth_row
from gevsim.pixel._fastmath import expf, logf
from gevsim.pixel.mechanisms._base import (
    STREAM_CASCADED_OUTPUT,
    STREAM_OUTPUT_POLES,
    STREAM_PHOTORECEPTOR,
    STREAM_PHOTORECEPTOR_OUTPUT,
)

BLOCK = 1024  # pixels per parallel work item (fixed, so results do not depend on threads)
_TWO_PI = 2.0 * math.pi


#: 2^64 / golden ratio (odd): the Weyl increment of SplitMix64 (Steele, Lea & Flood, OOPSLA 2014).
GOLDEN = np.uint64(0x9E3779B97F4A7C15)


@njit(inline="always")
def mix64(x):
    """SplitMix64's finaliser, a bijection of 64-bit integers with full avalanche (Steele, Lea &
    Flood 2014, with the multipliers of D. Stafford's "Mix13", 2011)."""
    x = np.uint64(x)
    x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return x ^ (x >> np.uint64(31))


@njit(inline="always")
def stream_key(key, step, stream):
    """64-bit key of one noise stream (shot, read, 1/f poles) at one global step; pixel ``i``'s
    deviate is then ``normal(pixel_bits(stream_key, i))``."""
    k = mix64(np.uint64(key) + np.uint64(step) * GOLDEN)
    return mix64(k ^ mix64(np.uint64(stream) * GOLDEN + np.uint64(0x632BE59BD9B4E019)))


@njit(inline="always")
def pixel_bits(skey, pixel):
    """The 32 bits that make pixel ``pixel``'s deviate of a stream key: the top half of
    mix64(skey + pixel * GOLDEN)."""
    return np.uint32(mix64(skey + np.uint64(pixel) * GOLDEN) >> np.uint64(32))


_F = np.float32


@njit(inline="always")
def _half_uniform(h):
    """The sign (+-1) and p in (0, 1/2] that a 32-bit hash ``h`` stands for: the top bit is
    the sign, the other 31 give p."""
    sign = _F(1.0) - _F(2.0) * _F(np.int32(h >> np.uint32(31)))
    p = (_F(np.int32(h & np.uint32(0x7FFFFFFF))) + _F(0.5)) * _F(1.0 / 4294967296.0)
    return sign, p


#: Below this p, Acklam's lower-tail branch is used (p_low of his algorithm).
_P_LOW = _F(0.02425)


@njit(inline="always")
def _central(p):
    """Acklam's central branch of the inverse normal CDF at p (used for p >= _P_LOW)."""
    q = p - _F(0.5)
    r = q * q
    return ((((((_F(-3.969683028665376e01) * r + _F(2.209460984245205e02)) * r
                + _F(-2.759285104469687e02)) * r + _F(1.383577518672690e02)) * r
              + _F(-3.066479806614716e01)) * r + _F(2.506628277459239e00)) * q
            / (((((_F(-5.447609879822406e01) * r + _F(1.615858368580409e02)) * r
                  + _F(-1.556989798598866e02)) * r + _F(6.680131188771972e01)) * r
                + _F(-1.328068155288572e01)) * r + _F(1.0)))


@njit(inline="always")
def _tail(p):
    """Acklam's lower-tail branch at p (used for p < _P_LOW)."""
    t = np.sqrt(_F(-2.0) * logf(p))
    return (((((_F(-7.784894002430293e-03) * t + _F(-3.223964580411365e-01)) * t + _F(-2.400758277161838e00)) * t
              + _F(-2.549732539343734e00)) * t + _F(4.374664141464968e00)) * t + _F(2.938163982698783e00)) / (
        (((_F(7.784695709041462e-03) * t + _F(3.224671290700398e-01)) * t + _F(2.445134137142996e00)) * t
         + _F(3.754408661907416e00)) * t + _F(1.0))


@njit(inline="always")
def normal(h):
    """Standard normal deviate (float32) from a 32-bit hash ``h`` by inversion.

    The top bit is the sign; the other 31 give p in (0, 1/2], mapped through
    Acklam's rational inverse normal CDF (central and lower-tail branches,
    relative error 1.2e-9 in double; here single precision, ~1e-7). |z| reaches
    6.3 (p = 2^-32). Loops over many deviates use :func:`normals_row`, which gives
    the same bits faster.
    """
    sign, p = _half_uniform(h)
    return sign * (_tail(p) if p < _P_LOW else _central(p))


@njit(inline="never", error_model="numpy", fastmath={"nnan", "ninf"}, cache=True)
def _central_row(skey, z, sp):
    """Central-branch deviates z of pixels 0 .. len(z) - 1 of a stream key, and their signed
    p (sign * p, exact), from which :func:`_tail_row` finds and redoes the tail pixels
    (branch-free: vectorised)."""
    for i in range(z.shape[0]):
        sign, p = _half_uniform(pixel_bits(skey, i))
        z[i] = sign * _central(p)
        sp[i] = sign * p
    return 0


@njit(inline="never", error_model="numpy", fastmath={"nnan", "ninf"}, cache=True)
def _tail_row(z, sp, idx, p_tail):
    """Replace the deviates of the pixels with p < 0.02425 by the tail branch: list them
    (branch-free), compute the branch for the list (contiguous, vectorised), put the results back."""
    m = 0
    for i in range(z.shape[0]):
        q = sp[i]
        idx[m] = i
        p_tail[m] = q
        m += abs(q) < _P_LOW
    for j in range(m):
        q = p_tail[j]
        p_tail[j] = (_F(1.0) if q > _F(0.0) else _F(-1.0)) * _tail(abs(q))
    for j in range(m):
        z[idx[j]] = p_tail[j]
    return 0


@njit(cache=True)
def normals_row(skey, z, sp, idx):
    """Deviates ``normal(pixel_bits(skey, i))`` of pixels i = 0 .. len(z) - 1, bit for bit;
    sp (float32, twice z's length) and idx (int64, z's length) are scratch.

    The central branch runs vectorised over all pixels; the lower tail (p < 0.02425, about
    one pixel in twenty) is computed for those pixels only, also vectorised, so the log and
    square root of the tail are not paid for the other 95 %."""
    _central_row(skey, z, sp)
    _tail_row(z, sp, idx, sp[z.shape[0]:])


@njit(cache=True)
def normals(key, step, count, stream):
    """``count`` deviates of one (key, step, stream), pixels 0 .. count - 1: for tests of the generator."""
    out = np.empty(count)
    sk = stream_key(key, step, stream)
    for p in range(count):
        out[p] = normal(pixel_bits(sk, p))
    return out


@njit(cache=True)
def normals_fast(key, step, count, stream):
    """The same deviates as :func:`normals`, through :func:`normals_row` (for tests that the two agree)."""
    z = np.empty(count, np.float32)
    normals_row(stream_key(key, step, stream), z, np.empty(2 * count, np.float32), np.empty(count, np.int64))
    return z.astype(np.float64)


@njit(inline="always")
def _filter_input(cur, gain, dark, v1, fc_per_a, fc_max, d, filt):
    """Total photocurrent, its log u, the cutoff fc, the first pole's decay a over the step
    and the distance e1 of its state from u."""
    itot = np.float64(cur) * gain + dark
    u = np.float64(logf(np.float32(itot)))
    fc = min(fc_per_a * itot, fc_max)
    a = np.float64(expf(np.float32(-_TWO_PI * fc * d))) * filt
    return itot, u, fc, a, v1 - u


@njit(inline="always")
def _shot_noise(shot_q, amp, fc, itot, a, z):
    """The shot-noise term added to the first pole's state over a step (exact for the
    Ornstein-Uhlenbeck transition), driven by the deviate z."""
    return np.float64(np.sqrt(np.float32((shot_q * fc / itot + amp / fc) * (1.0 - a * a))) * z)


@njit(inline="never", error_model="numpy", fastmath={"nnan", "ninf"}, cache=True)
def _photoreceptor_row(cur, gain, dark, v1, out, z, d, fc_per_a, fc_max, filt, shot_q, amp):
    """One step of the photoreceptor without an output pole, for a contiguous run of pixels:
    branch-free so that LLVM vectorises it. z holds the pixels' shot-noise deviates (read only
    when shot_q > 0). One loop per case, so that none computes what it discards. Filter states
    stay in double precision. (With an output pole: :func:`gevsim.pixel._cascade.smooth_row`.)"""
    n = cur.shape[0]
    if shot_q > 0.0 or amp > 0.0:
        for p in range(n):
            itot, u, fc, a, e1 = _filter_input(cur[p], gain[p], dark[p], v1[p], fc_per_a, fc_max, d, filt)
            x = u + a * e1 + _shot_noise(shot_q, amp, fc, itot, a, z[p])
            v1[p] = x
            out[p] = np.float32(x)
    else:
        for p in range(n):
            itot, u, fc, a, e1 = _filter_input(cur[p], gain[p], dark[p], v1[p], fc_per_a, fc_max, d, filt)
            x = u + a * e1
            v1[p] = x
            out[p] = np.float32(x)
    return 0


@njit(inline="never", error_model="numpy", fastmath={"nnan", "ninf"}, cache=True)
def _ou_row(state, out, z, alpha, scale):
    """Add one Ornstein-Uhlenbeck noise process (exact transition) to a run of pixels,
    driven by the deviates z."""
    for p in range(state.shape[0]):
        s = alpha * state[p] + scale * np.float64(z[p])
        state[p] = s
        out[p] = np.float32(np.float64(out[p]) + s)
    return 0


@njit(cache=True)
def _step_tables(dt, fn_hz, fn_var, key, step0, beta, has2, smooth_read):
    """Per-step tables of :func:`photoreceptor` (compiled apart from its parallel loop, which compiles
    ~2x faster without them): each Ornstein-Uhlenbeck pole's decay and scale, the stream keys, the output
    pole's b2 and 1 - b2 and the smoothed read noise's coefficients."""
    T = dt.shape[0]
    M = fn_hz.shape[0]
    fn_alpha = np.empty((T, M))
    fn_scale = np.empty((T, M))
    keys = np.empty((T, M + 3), np.uint64)
    steps = np.empty((T, 2))  # b2, 1 - b2 of the output pole
    read = np.zeros((T, 6))
    for t in range(T):
        keys[t, 0] = stream_key(key, step0 + t, STREAM_PHOTORECEPTOR)
        keys[t, M + 1] = stream_key(key, step0 + t, STREAM_PHOTORECEPTOR_OUTPUT)
        keys[t, M + 2] = stream_key(key, step0 + t, STREAM_CASCADED_OUTPUT)
        for m in range(M):
            alpha = exp_scalar(-_TWO_PI * fn_hz[m] * dt[t])
            fn_alpha[t, m] = alpha
            fn_scale[t, m] = math.sqrt(fn_var[m] * (1.0 - alpha * alpha))
            keys[t, m + 1] = stream_key(key, step0 + t, STREAM_OUTPUT_POLES + m)
        eb2 = -expm1_scalar(-beta * dt[t]) if has2 else 1.0
        steps[t, 0], steps[t, 1] = 1.0 - eb2, eb2
        if smooth_read:
            a_r, c_det, s1, r, s2, c = read_coefficients(fn_var[0], _TWO_PI * fn_hz[0], beta, dt[t])
            read[t, 0], read[t, 1], read[t, 2], read[t, 3], read[t, 4], read[t, 5] = a_r, c_det, s1, r, s2, c
    return fn_alpha, fn_scale, keys, steps, read


@njit(parallel=True, nogil=True, cache=True)
def photoreceptor(current, dt, gain, dark, v1, v2, fn, fn_hz, fn_var, key, step0,
                  fc_ref, i_ref, fc_max, f2, shot_q, amp, n_read, out):
    """Advance the photoreceptor over T steps of held photocurrent. (Over 80 lines: one compiled loop
    over blocks and steps, so that no state leaves the CPU caches between stages.)

    The noise arguments are the sums of :func:`gevsim.pixel.mechanisms.kernel_noise` (shot_q, amp,
    fn_hz, fn_var, n_read); the random streams are the named ``STREAM_*`` of
    :mod:`gevsim.pixel.mechanisms._base`.

    current (T, P) photocurrent (A) held over each step of duration dt (T,) s,
    finite and with current * gain + dark > 0 (checked by the caller);
    gain, dark (P,) fixed patterns; v1, v2 (P,) filter states in ln units;
    fn (M, P) states of Ornstein-Uhlenbeck noise (band-limited read noise, the first
    ``n_read`` (0 or 1) of them, then 1/f poles) with corner frequencies fn_hz (M,) and
    variances fn_var (M,); all updated in place. out (T, P) receives the output
    in ln units. amp > 0: the photoreceptor amplifier's noise that the feedback loop leaves,
    variance amp / f_c on the photoreceptor pole (needs a finite bandwidth).
    fc_ref <= 0 means infinite bandwidth (no filter); shot_q = elementary
    charge * pi to enable shot noise, else 0. f2 > 0: the output pole (source follower,
    change amplifier input), through which the shot and read noise pass after their own
    poles (:mod:`gevsim.pixel._cascade`: smooth, exact for any step); f2 <= 0: none, and the
    read noise is added to the output. 1/f poles are added to the output in either case.
    The noise of pixel ``j`` hashes ``stream_key + j * GOLDEN`` whatever block it is in, so
    it depends on neither the blocks nor the threads.
    """
    T, P = current.shape
    M = fn.shape[0]
    if fc_ref > 0:
        fc_per_a, fcm, filt = fc_ref / i_ref, fc_max, 1.0
    else:
        fc_per_a, fcm, filt = 0.0, 0.0, 0.0  # no filter: a = 0
    has2 = f2 > 0
    smooth_read = has2 and n_read > 0
    beta = _TWO_PI * f2
    fn_alpha, fn_scale, keys, steps, read = _step_tables(dt, fn_hz, fn_var, key, step0, beta, has2, smooth_read)
    nblocks = (P + BLOCK - 1) // BLOCK
    shot = shot_q > 0 or amp > 0
    first_ou = n_read if smooth_read else 0
    for b in prange(nblocks):
        lo = b * BLOCK
        hi = min(P, lo + BLOCK)
        z = np.empty(hi - lo, np.float32)
        z2 = np.empty(hi - lo, np.float32)
        zr = np.empty(hi - lo, np.float32)
        zr2 = np.empty(hi - lo, np.float32)
        # Without read noise smooth_row gets this unused state, not v2: aliasing v2 made LLVM's
        # overlap check fail at run time and run the scalar loop (--no-noise was 1.7x slower than noise).
        rd_none = np.zeros(hi - lo)
        sp = np.empty(2 * (hi - lo), np.float32)
        idx = np.empty(hi - lo, np.int64)
        for t in range(T):
            d = dt[t]
            b2 = steps[t, 0]
            # Pixel lo + i of a stream hashes key + (lo + i) GOLDEN.
            if shot:
                normals_row(keys[t, 0] + np.uint64(lo) * GOLDEN, z, sp, idx)
            if has2:
                if shot:
                    normals_row(keys[t, M + 1] + np.uint64(lo) * GOLDEN, z2, sp, idx)
                if smooth_read:
                    normals_row(keys[t, 1] + np.uint64(lo) * GOLDEN, zr, sp, idx)
                    normals_row(keys[t, M + 2] + np.uint64(lo) * GOLDEN, zr2, sp, idx)
                r_coef = (read[t, 0], read[t, 1], read[t, 2], read[t, 3], read[t, 4], read[t, 5])
                smooth_row(current[t, lo:hi], gain[lo:hi], dark[lo:hi], v1[lo:hi], v2[lo:hi],
                           fn[0, lo:hi] if smooth_read else rd_none, out[t, lo:hi], z, z2, zr, zr2, d, fc_per_a,
                           fcm, filt, shot_q, amp, beta, b2, steps[t, 1], smooth_read, r_coef)
            else:
                _photoreceptor_row(current[t, lo:hi], gain[lo:hi], dark[lo:hi], v1[lo:hi], out[t, lo:hi], z, d,
                                   fc_per_a, fcm, filt, shot_q, amp)
            for m in range(first_ou, M):
                normals_row(keys[t, m + 1] + np.uint64(lo) * GOLDEN, z, sp, idx)
                _ou_row(fn[m, lo:hi], out[t, lo:hi], z, fn_alpha[t, m], fn_scale[t, m])
