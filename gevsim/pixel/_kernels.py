"""Compiled inner loops of the photoreceptor and its noise (numba).

Noise comes from a counter-based generator: a 32-bit integer hash of
(key, global step, pixel, stream) mapped to a standard normal through a
65,536-bin inverse-CDF table with linear interpolation inside each bin and
an exact tail (Acklam's rational approximation, relative error 1.2e-9) in
the two outermost bins. A draw depends only on its counter, so results are
identical for any chunking of time and any number of threads, bit for bit.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from scipy.special import ndtri

_BITS = 16
_NBINS = 1 << _BITS
#: Inverse normal CDF at the bin edges k / 65536 (the two infinite edges are never used).
NORMAL_TABLE = ndtri(np.arange(_NBINS + 1) / _NBINS).astype(np.float32)  # 256 KiB: stays in L2 cache
NORMAL_TABLE[0], NORMAL_TABLE[-1] = NORMAL_TABLE[1], NORMAL_TABLE[-2]
BLOCK = 1024  # pixels per parallel work item (fixed, so results do not depend on threads)
_TWO_PI = 2.0 * math.pi


@njit(inline="always")
def mix32(x):
    """A 32-bit integer hash with good avalanche ("lowbias32", C. Wellons, 2018)."""
    x = np.uint32(x)
    x ^= x >> np.uint32(16)
    x = np.uint32(x * np.uint32(0x7FEB352D))
    x ^= x >> np.uint32(15)
    x = np.uint32(x * np.uint32(0x846CA68B))
    x ^= x >> np.uint32(16)
    return x


@njit(inline="always")
def step_key(key, step):
    """Per-step key from the generator key and a 64-bit global step index."""
    lo = np.uint32(step & 0xFFFFFFFF)
    hi = np.uint32((step >> 32) & 0xFFFFFFFF)
    return mix32(np.uint32(key) ^ mix32(lo ^ mix32(hi ^ np.uint32(0x5BD1E995))))


@njit(inline="always")
def _tail(p):
    # Acklam's inverse normal CDF, lower region (p < 0.02425).
    q = math.sqrt(-2.0 * math.log(p))
    num = ((((-7.784894002430293e-03 * q - 3.223964580411365e-01) * q - 2.400758277161838e00) * q
            - 2.549732539343734e00) * q + 4.374664141464968e00) * q + 2.938163982698783e00
    den = (((7.784695709041462e-03 * q + 3.224671290700398e-01) * q + 2.445134137142996e00) * q
           + 3.754408661907416e00) * q + 1.0
    return num / den


@njit(inline="always")
def normal(h, table):
    """Standard normal deviate from a 32-bit hash ``h``."""
    i = np.int64(h >> np.uint32(16))
    frac = np.float64(h & np.uint32(0xFFFF)) * (1.0 / 65536.0)
    if i == 0:
        return _tail((frac + 0.5 / 65536.0) / 65536.0)
    if i == 65535:
        return -_tail((1.0 - frac - 0.5 / 65536.0) / 65536.0)
    lo = np.float64(table[i])
    return lo + frac * (np.float64(table[i + 1]) - lo)


@njit(inline="always")
def stream_key(key, step, stream):
    """Key of one noise stream (shot, read, 1/f poles) at one step; a pixel's
    deviate is then ``normal(mix32(stream_key ^ pixel))``: one hash per deviate."""
    return mix32(step_key(key, step) ^ mix32(np.uint32(stream) * np.uint32(0x9E3779B9)))


@njit(cache=True)
def normals(key, step, count, stream, table):
    """``count`` deviates of one (key, step, stream): for tests of the generator."""
    out = np.empty(count)
    sk = stream_key(key, step, stream)
    for p in range(count):
        out[p] = normal(mix32(sk ^ np.uint32(p)), table)
    return out


@njit(parallel=True, cache=True)
def photoreceptor(current, dt, gain, dark, v1, v2, fn, fn_hz, fn_var, key, step0,
                  fc_ref, i_ref, fc_max, f2, shot_q, table, out):
    """Advance the photoreceptor over T steps of held photocurrent.

    current (T, P) photocurrent (A) held over each step of duration dt (T,) s;
    gain, dark (P,) fixed patterns; v1, v2 (P,) filter states in ln units,
    fn (M, P) states of Ornstein-Uhlenbeck noise added to the output (band-limited
    read noise, 1/f poles) with corner frequencies fn_hz (M,) and variances fn_var (M,), all updated in place; out (T, P) receives the output
    in ln units. fc_ref <= 0 means infinite bandwidth (no filter); f2 <= 0 no
    second pole; shot_q = elementary charge * pi to enable shot noise, else 0.
    Returns the number of photocurrents that were negative, not finite or gave a
    zero total current (then
    the states are left partly updated and must be discarded by the caller).
    """
    T, P = current.shape
    M = fn.shape[0]
    fc_per_a = fc_ref / i_ref
    nblocks = (P + BLOCK - 1) // BLOCK
    bad = np.zeros(nblocks, np.int64)
    # 1/f poles: their decay and innovation scale depend on the step only.
    fn_alpha = np.empty((T, M))
    fn_scale = np.empty((T, M))
    for t in range(T):
        for m in range(M):
            alpha = math.exp(-_TWO_PI * fn_hz[m] * dt[t])
            fn_alpha[t, m] = alpha
            fn_scale[t, m] = math.sqrt(fn_var[m] * (1.0 - alpha * alpha))
    for b in prange(nblocks):
        lo = b * BLOCK
        hi = min(P, lo + BLOCK)
        for t in range(T):
            d = dt[t]
            k_shot = stream_key(key, step0 + t, 1)
            k_fn = np.empty(M, np.uint32)
            for m in range(M):
                k_fn[m] = stream_key(key, step0 + t, 3 + m)
            b2 = math.exp(-_TWO_PI * f2 * d) if f2 > 0 else 0.0
            for p in range(lo, hi):
                i_ph = current[t, p]
                if not (i_ph >= 0.0 and i_ph < np.inf):
                    bad[b] += 1
                    continue
                itot = i_ph * gain[p] + dark[p]
                if itot <= 0.0:
                    bad[b] += 1
                    continue
                # Single-precision log and exp (glibc logf/expf, < 1 ulp): their
                # error (~2e-6 in ln units) is far below any threshold or noise
                # level; the filter states stay in double precision.
                u = np.float64(math.log(np.float32(itot)))
                if fc_ref > 0:
                    fc = min(fc_per_a * itot, fc_max)
                    a = np.float64(math.exp(np.float32(-_TWO_PI * fc * d)))
                else:
                    fc = np.inf
                    a = 0.0
                e1 = v1[p] - u
                x = u + a * e1
                if shot_q > 0.0:
                    # Exact Ornstein-Uhlenbeck transition: stationary variance pi q fc / I.
                    # (single precision: a noise amplitude needs no more)
                    x += np.float64(math.sqrt(np.float32(shot_q * fc / itot * (1.0 - a * a)))) * normal(
                        mix32(k_shot ^ np.uint32(p)), table)
                v1[p] = x
                if f2 > 0:
                    if fc_ref > 0:
                        tau1 = 1.0 / (_TWO_PI * fc)
                        tau2 = 1.0 / (_TWO_PI * f2)
                        if abs(tau1 - tau2) > 1e-9 * tau2:
                            c = tau1 * (a - b2) / (tau1 - tau2)
                        else:
                            c = d / tau2 * b2
                    else:
                        c = 0.0
                    y = u + b2 * (v2[p] - u) + c * e1
                    v2[p] = y
                else:
                    y = x
                for m in range(M):
                    s = fn_alpha[t, m] * fn[m, p] + fn_scale[t, m] * normal(
                        mix32(k_fn[m] ^ np.uint32(p)), table)
                    fn[m, p] = s
                    y += s
                out[t, p] = y
    return bad.sum()
