"""Noise through two poles, exact for any time step (issue 22).

A single pole driven by white noise (an Ornstein-Uhlenbeck path) has an infinite rate of
level crossings: sampled every dt, comparators count more crossings the smaller dt (the
sensor-physics audit measured gradient noise events 1,691 -> 7,724 ev/px/s from 40 to 5 us).
Real pixels band-limit their noise with at least two poles: the photoreceptor, then the
source follower and the change amplifier or comparator inputs. Here every noise that reaches
the output passes through the fixed output pole (``second_pole_hz``, rate beta) after its own
pole (rate alpha): photodiode shot noise after the photoreceptor's light-dependent pole, read
noise after its ``read_noise_bandwidth_hz`` pole. The output is then differentiable and crossing
counts converge as dt shrinks.

Over a step of length d with the poles held, the noise added to a pole's state x and to the
output y is a pair of correlated normals, drawn exactly. With white noise of stationary
variance var at x, and q the same noise through a pole at beta, y's noise is
c (x_n - q_n), c = beta / (beta - alpha) (partial fractions of the cascade), and

    Var x_n = var (1 - a^2),  Var q_n = var (alpha / beta) (1 - b^2),
    Cov = var 2 alpha / (alpha + beta) (1 - a b),   a = exp(-alpha d), b = exp(-beta d),

computed from 1 - a and 1 - b (no cancellation as d -> 0). Stationary start: x_n ~ N(0, var)
and y_n = beta / (alpha + beta) x_n + sqrt(var alpha beta) / (alpha + beta) z.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, vectorize

from gevsim._portable import expm1_scalar
from gevsim.pixel._fastmath import expf, logf

_F = np.float32
_TWO_PI = 2.0 * math.pi


@njit(inline="always")
def one_minus_exp(x):
    """1 - exp(-x) for x >= 0 to ~1e-7 relative, branch-free: a Taylor series below 1/8 (no
    cancellation as x -> 0), single-precision exp above."""
    s = min(x, 0.125)
    small = s * (1.0 - s * (0.5 - s * (1.0 / 6.0 - s * (1.0 / 24.0 - s * (1.0 / 120.0 - s / 720.0)))))
    big = 1.0 - np.float64(expf(_F(-x)))
    return small if x < 0.125 else big


#: Poles closer than this (relative) are moved apart to it: c = beta / (beta - alpha) would
#: amplify the rounding of 1 - a and 1 - b (1e-7) without bound. A 1 % shift of a pole is far
#: below what any preset's pole is known to.
POLE_GAP = 0.01


@njit(inline="always")
def separate(alpha, beta):
    """alpha, moved to 1 % from beta when closer (on its own side)."""
    if abs(beta - alpha) < POLE_GAP * beta:
        return beta * (1.0 - POLE_GAP) if alpha <= beta else beta * (1.0 + POLE_GAP)
    return alpha


@vectorize(["float64(float64, float64)"], cache=True)
def separated_hz(f_hz, f_out_hz):
    """:func:`separate` over arrays (in any unit, here Hz): for the stationary start, which must
    follow the kernel's law."""
    return separate(f_hz, f_out_hz)


@njit(inline="always")
def pair_coefficients(var, alpha, beta, ea, eb):
    """(s1, r, s2, c): x_n = s1 z1 and y_n = c ((s1 - r) z1 - s2 z2) for independent standard
    normals z1, z2 (the module docstring's pair; ea = 1 - a, eb = 1 - b; alpha at least
    :data:`POLE_GAP` from beta, see :func:`separate`)."""
    gap = beta - alpha
    vx = var * ea * (2.0 - ea)
    vq = var * (alpha / beta) * eb * (2.0 - eb)
    cov = var * 2.0 * alpha / (alpha + beta) * (ea + eb - ea * eb)
    s1 = math.sqrt(vx)
    r = cov / max(s1, 1e-300)
    s2 = math.sqrt(max(vq - r * r, 0.0))
    return s1, r, s2, beta / gap


@njit(inline="always")
def stationary_pair(var, alpha, beta, z1, z2):
    """(x_n, y_n) from the stationary joint law of the cascade's noise."""
    s = math.sqrt(var)
    xn = s * z1
    return xn, beta / (alpha + beta) * xn + s * math.sqrt(alpha * beta) / (alpha + beta) * z2


@njit(inline="never", error_model="numpy", fastmath={"nnan", "ninf"}, cache=True)
def smooth_row(cur, gain, dark, v1, v2, rd, out, zs1, zs2, zr1, zr2, d, fc_per_a, fc_max, filt, shot_q, amp,
               beta, b2, eb2, has_read, r_coef):
    """One step of the photoreceptor (pole 1), the read-noise pole and the output pole for a run
    of pixels, every noise through two poles. v1 photoreceptor state, v2 output, rd read-noise
    state (ln units), updated in place; out receives the output (float32). zs*, zr* are the
    step's standard normals for shot and read noise; the photoreceptor pole's noise has variance
    shot_q f_c / I (shot noise) + amp / f_c (the amplifier's noise the loop leaves).
    r_coef = (a_r, c_det, s1, r, s2, c) of the read-noise pole for this step (the same for every pixel)."""
    a_r, c_det_r, rs1, rr, rs2, rc = r_coef
    for p in range(cur.shape[0]):
        itot = np.float64(cur[p]) * gain[p] + dark[p]
        u = np.float64(logf(_F(itot)))
        fc = min(fc_per_a * itot, fc_max)
        alpha = separate(_TWO_PI * fc, beta)
        fc = alpha / _TWO_PI
        ea = one_minus_exp(alpha * d) * filt + (1.0 - filt)
        a = 1.0 - ea
        e1 = v1[p] - u
        # held input, exact; without a photoreceptor filter (filt = 0) x jumps to u: no coupling
        y = u + b2 * (v2[p] - u) + filt * beta / (beta - alpha) * (a - b2) * e1
        x = u + a * e1
        if shot_q > 0.0 or amp > 0.0:
            var = shot_q * fc / itot + amp / fc
            s1, r, s2, c = pair_coefficients(var, alpha, beta, ea, eb2)
            z1 = np.float64(zs1[p])
            xn = s1 * z1
            x += xn
            y += c * (xn - (r * z1 + s2 * np.float64(zs2[p])))
        if has_read:
            r0 = rd[p]
            z1 = np.float64(zr1[p])
            rn = rs1 * z1
            y += c_det_r * r0 + rc * (rn - (rr * z1 + rs2 * np.float64(zr2[p])))
            rd[p] = a_r * r0 + rn
        v1[p] = x
        v2[p] = y
        out[p] = np.float32(y)
    return 0


@njit(cache=True)
def read_coefficients(var, alpha, beta, d):
    """The per-step constants of the read-noise pole (rate alpha, stationary variance var)
    feeding the output pole (rate beta): (a_r, c_det, s1, r, s2, c), where c_det multiplies the
    read-noise state's deterministic decay into the output."""
    alpha = separate(alpha, beta)
    ea = -expm1_scalar(-alpha * d)
    eb = -expm1_scalar(-beta * d)
    s1, r, s2, c = pair_coefficients(var, alpha, beta, ea, eb)
    return 1.0 - ea, c * ((1.0 - ea) - (1.0 - eb)), s1, r, s2, c
