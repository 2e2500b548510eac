"""Elementary functions and sums that give the same bits on every x86-64 CPU.

Three libraries pick their code by the CPU they run on, and give last-bit-different results:

- numpy 2.x dispatches its ``exp``/``log`` (and others) to AVX-512 kernels where the CPU has
  them and to AVX2 or scalar code elsewhere (FACTS.md: a clone failed 3 pins on an AVX2-only
  AMD EPYC that passed on an AVX-512 Xeon);
- glibc's libm (``math.exp``, numba's ``math.exp``, numpy's ``sin``/``cos``) chooses FMA or SSE2
  variants of ``exp``, ``log``, ``sin``, ``pow`` at load time (measured here: 200,000 arguments
  hash differently under ``GLIBC_TUNABLES=glibc.cpu.hwcaps=-AVX2,-FMA``);
- OpenBLAS (numpy's ``@``/``tensordot``) picks a GEMM kernel per CPU (``OPENBLAS_CORETYPE=Nehalem``
  changes the bits of a (300, 2) x (2, 5000) product).

Everything here is written with the operations IEEE 754 defines to the bit (+, -, *, /,
sqrt, floor, frexp/ldexp) and compiled by numba, which sets no fast-math or ``contract`` flag:
LLVM neither fuses a multiply and an add nor reorders sums, whatever CPU it targets
(``NUMBA_CPU_NAME=generic`` and the host give the same bits: ``tests/test_portable.py``).
The algorithms are the textbook ones (Cody-Waite argument reduction, Taylor series to
below half an ulp, the ``log1p`` identity 2 atanh(f / (2 + f))); accuracy against an 80-bit
reference (``tests/test_portable.py``): exp, log below 1 ulp; expm1, log10, and sin and cos
on |x| < 4 below 1.6 ulp; sin and cos on |x| < 1.6e6 (where the reduction by pi/2 is exact),
atan and tan below 2.6 ulp. Every code path that decides events or reconstructions uses these instead of numpy's,
libm's or BLAS's (``tests/test_architecture.py`` checks the source).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange, vectorize

__all__ = ["exp", "expm1", "log", "log10", "sin", "cos", "tan", "atan", "combine", "weighted_sum"]

# ln 2 split so that k * LN2_HI is exact for |k| < 2**21 (the low 21 bits of LN2_HI are zero).
_LN2_HI = float.fromhex("0x1.62e42fee00000p-1")
_LN2_LO = float.fromhex("0x1.a39ef35793c76p-33")
_INV_LN2 = float.fromhex("0x1.71547652b82fep+0")
_INV_LN10 = float.fromhex("0x1.bcb7b1526e50ep-2")
_SQRT_HALF = float.fromhex("0x1.6a09e667f3bcdp-1")
# pi/2 in three parts of 33, 33 and 53 bits: n * part is exact for |n| < 2**20.
_PIO2_1 = float.fromhex("0x1.921fb54400000p+0")
_PIO2_2 = float.fromhex("0x1.0b4611a600000p-34")
_PIO2_3 = float.fromhex("0x1.3198a2e037073p-69")
_TWO_OVER_PI = float.fromhex("0x1.45f306dc9c883p-1")
_PI_2 = float.fromhex("0x1.921fb54442d18p+0")  # pi/2 rounded
_PI_2_LO = float.fromhex("0x1.1a62633145c07p-54")  # pi/2 - _PI_2
_PI_4 = 0.5 * _PI_2
_PI_4_LO = 0.5 * _PI_2_LO
_TAN_PI_8 = float.fromhex("0x1.a827999fcef32p-2")  # sqrt(2) - 1
_POW10 = tuple(float(10**k) for k in range(23))  # exact doubles
_EXP_MAX = 709.782712893384  # exp overflows above (ln of the largest double)
_EXP_MIN = -745.1332191019412  # exp underflows to 0 below (ln of half the smallest subnormal)

# Taylor coefficients, each a correctly rounded quotient (the same bits everywhere).
_E = tuple(1.0 / math.factorial(n) for n in range(2, 14))  # exp(r) - 1 - r = r^2 (E[0] + E[1] r + ...)
_L = tuple(2.0 / (2 * j + 1) for j in range(1, 12))  # 2 atanh(s) - 2 s = s z (L[0] + L[1] z + ...)
_S = tuple((-1.0 if k % 2 else 1.0) / math.factorial(2 * k + 1) for k in range(1, 9))  # sin
_C = tuple((-1.0 if k % 2 else 1.0) / math.factorial(2 * k) for k in range(2, 10))  # cos beyond 1 - z/2
_A = tuple((-1.0 if k % 2 else 1.0) / (2 * k + 1) for k in range(1, 22))  # atan


@njit(inline="always", cache=True)
def _horner(c, x):
    """c[0] + c[1] x + c[2] x^2 + ... (c a tuple), highest power first."""
    y = c[len(c) - 1]
    for i in range(len(c) - 2, -1, -1):
        y = y * x + c[i]
    return y


@njit(inline="always", cache=True)
def _reduce_ln2(x):
    """k, r_hi, r_lo with x = k ln2 + (r_hi - r_lo), |r| <= ln2 / 2; r_hi is exact."""
    k = math.floor(x * _INV_LN2 + 0.5)
    return k, x - k * _LN2_HI, k * _LN2_LO


@njit(inline="always", cache=True)
def exp_scalar(x):
    """exp(x) of a float64."""
    if x != x:
        return x
    if x > _EXP_MAX:
        return math.inf
    if x < _EXP_MIN:
        return 0.0
    k, r_hi, r_lo = _reduce_ln2(x)
    r = r_hi - r_lo
    y = 1.0 + (r_hi - (r_lo - r * r * _horner(_E, r)))
    return math.ldexp(y, int(k))  # exact (a single rounding where the result is subnormal)


@njit(inline="always", cache=True)
def expm1_scalar(x):
    """exp(x) - 1 of a float64, accurate near 0."""
    if x != x:
        return x
    if x > _EXP_MAX:
        return math.inf
    if x < -40.0:
        return -1.0
    k, r_hi, r_lo = _reduce_ln2(x)
    r = r_hi - r_lo
    p = r_hi - (r_lo - r * r * _horner(_E, r))  # exp(r) - 1
    if k == 0.0:
        return p
    if k > 56.0:  # exp(x) - 1 rounds to exp(x); 2^k alone could overflow
        return exp_scalar(x)
    two_k = math.ldexp(1.0, int(k))
    return two_k * p + (two_k - 1.0)


@njit(inline="always", cache=True)
def log_scalar(x):
    """Natural log of a float64 (-inf at 0, NaN below)."""
    if x != x or x < 0.0:
        return math.nan
    if x == 0.0:
        return -math.inf
    if x == math.inf:
        return x
    m, e = math.frexp(x)  # x = m 2^e, m in [1/2, 1), exact (subnormals included)
    if m < _SQRT_HALF:
        m = 2.0 * m
        e -= 1
    f = m - 1.0  # exact, |f| < 0.42
    s = f / (2.0 + f)
    z = s * s
    r = z * _horner(_L, z)  # log(1 + f) = f - (f^2/2 - s (f^2/2 + r))
    hfsq = 0.5 * f * f
    k = float(e)
    return k * _LN2_HI - ((hfsq - (s * (hfsq + r) + k * _LN2_LO)) - f)


@njit(inline="always", cache=True)
def _reduce_pio2(x):
    """n, r with x = n pi/2 + r, |r| <= pi/4 (accurate for |x| < 1.6e6, the same bits beyond)."""
    n = math.floor(x * _TWO_OVER_PI + 0.5)
    return n, ((x - n * _PIO2_1) - n * _PIO2_2) - n * _PIO2_3


@njit(inline="always", cache=True)
def _sin_poly(r):
    z = r * r
    return r + r * z * _horner(_S, z)


@njit(inline="always", cache=True)
def _cos_poly(r):
    z = r * r
    hz = 0.5 * z
    w = 1.0 - hz
    return w + (((1.0 - w) - hz) + z * z * _horner(_C, z))  # 1 - hz with its rounding error restored


@njit(inline="always", cache=True)
def _quadrant(n):
    q = int(n) % 4
    return q + 4 if q < 0 else q


@njit(inline="always", cache=True)
def sin_scalar(x):
    """sin(x) of a float64 (NaN at +-inf)."""
    if not abs(x) < math.inf:
        return math.nan
    n, r = _reduce_pio2(x)
    q = _quadrant(n)
    if q == 0:
        return _sin_poly(r)
    if q == 1:
        return _cos_poly(r)
    if q == 2:
        return -_sin_poly(r)
    return -_cos_poly(r)


@njit(inline="always", cache=True)
def cos_scalar(x):
    """cos(x) of a float64 (NaN at +-inf)."""
    if not abs(x) < math.inf:
        return math.nan
    n, r = _reduce_pio2(x)
    q = _quadrant(n)
    if q == 0:
        return _cos_poly(r)
    if q == 1:
        return -_sin_poly(r)
    if q == 2:
        return -_cos_poly(r)
    return _sin_poly(r)


@njit(inline="always", cache=True)
def _atan_poly(u):
    """atan(u) for |u| <= tan(pi/8)."""
    return u + u * (u * u) * _horner(_A, u * u)


@njit(inline="always", cache=True)
def atan_scalar(x):
    """atan(x) of a float64, in [-pi/2, pi/2]."""
    if x != x:
        return x
    a = abs(x)
    if a <= _TAN_PI_8:
        y = _atan_poly(a)
    elif a <= 1.0 / _TAN_PI_8:  # atan(a) = pi/4 + atan((a - 1) / (a + 1))
        y = _PI_4 + (_atan_poly((a - 1.0) / (a + 1.0)) + _PI_4_LO)
    else:  # atan(a) = pi/2 - atan(1 / a)
        y = _PI_2 - (_atan_poly(1.0 / a) - _PI_2_LO)
    return y if x >= 0.0 else -y


# numpy-style ufuncs over float64 (other real dtypes are cast to float64, as numpy's would be).
_SIG = ["float64(float64)"]


@vectorize(_SIG, cache=True)
def exp(x):
    """exp(x), the same bits on every CPU."""
    return exp_scalar(x)


@vectorize(_SIG, cache=True)
def expm1(x):
    """exp(x) - 1, accurate near 0, the same bits on every CPU."""
    return expm1_scalar(x)


@vectorize(_SIG, cache=True)
def log(x):
    """Natural log, the same bits on every CPU."""
    return log_scalar(x)


@vectorize(_SIG, cache=True)
def log10(x):
    """Base-10 log, the same bits on every CPU; exact at the powers of ten 1 ... 1e22."""
    y = log_scalar(x) * _INV_LN10
    n = math.floor(y + 0.5)
    if 0.0 <= n <= 22.0 and x == _POW10[int(n)]:
        return n
    return y


@vectorize(_SIG, cache=True)
def sin(x):
    """sin(x), the same bits on every CPU."""
    return sin_scalar(x)


@vectorize(_SIG, cache=True)
def cos(x):
    """cos(x), the same bits on every CPU."""
    return cos_scalar(x)


@vectorize(_SIG, cache=True)
def tan(x):
    """tan(x) = sin(x) / cos(x), the same bits on every CPU."""
    return sin_scalar(x) / cos_scalar(x)


@vectorize(_SIG, cache=True)
def atan(x):
    """atan(x), the same bits on every CPU."""
    return atan_scalar(x)


@njit(inline="never", cache=True)
def _sum_rows(o, w, b0, b1, b2, b3, k_n):
    """o[i] = ((w[0] b0[i] + w[1] b1[i]) + w[2] b2[i]) + w[3] b3[i], for the first k_n terms (k_n <= 4),
    in float64; contiguous slices, so LLVM vectorises it."""
    w0, w1, w2, w3 = w[0], w[1 % k_n], w[2 % k_n], w[3 % k_n]
    if k_n == 1:
        for i in range(o.shape[0]):
            o[i] = w0 * np.float64(b0[i])
    elif k_n == 2:
        for i in range(o.shape[0]):
            o[i] = w0 * np.float64(b0[i]) + w1 * np.float64(b1[i])
    elif k_n == 3:
        for i in range(o.shape[0]):
            o[i] = (w0 * np.float64(b0[i]) + w1 * np.float64(b1[i])) + w2 * np.float64(b2[i])
    else:
        for i in range(o.shape[0]):
            o[i] = ((w0 * np.float64(b0[i]) + w1 * np.float64(b1[i])) + w2 * np.float64(b2[i])) \
                + w3 * np.float64(b3[i])


@njit(inline="never", cache=True)
def _add_rows(o, w, b0, b1, b2, b3, k_n):
    """o[i] += ((w[0] b0[i] + ...)) for the next k_n terms; for more than four groups (in float64 o)."""
    for i in range(o.shape[0]):
        acc = np.float64(o[i]) + w[0] * np.float64(b0[i])
        if k_n > 1:
            acc = acc + w[1] * np.float64(b1[i])
        if k_n > 2:
            acc = acc + w[2] * np.float64(b2[i])
        if k_n > 3:
            acc = acc + w[3] * np.float64(b3[i])
        o[i] = acc


@njit(parallel=True, nogil=True, cache=True)
def _weighted_sum(w, b, out, block):
    """out[t, i] = (w[t, 0] b[0, i] + w[t, 1] b[1, i]) + ..., summed in float64 in group order
    (out is float64 when there are more than four groups), stored in out's dtype; blocks of rows
    in parallel."""
    t_n, k_n = w.shape
    n = b.shape[1]
    nb = (n + block - 1) // block
    for j in prange(t_n * nb):
        t = j // nb
        lo = (j % nb) * block
        hi = min(n, lo + block)
        o = out[t, lo:hi]
        m = min(k_n, 4)
        _sum_rows(o, w[t, :m], b[0, lo:hi], b[1 % k_n, lo:hi], b[2 % k_n, lo:hi], b[3 % k_n, lo:hi], m)
        for k in range(4, k_n, 4):
            m = min(k_n - k, 4)
            _add_rows(o, w[t, k:k + m], b[k, lo:hi], b[k + 1, lo:hi] if m > 1 else b[k, lo:hi],
                      b[k + 2, lo:hi] if m > 2 else b[k, lo:hi], b[k + 3, lo:hi] if m > 3 else b[k, lo:hi], m)


def weighted_sum(weights: np.ndarray, basis: np.ndarray, *, dtype: type = np.float64) -> np.ndarray:
    """``out[t, i] = sum_k weights[t, k] * basis[k, i]``, summed in float64 in the order k = 0, 1, ...

    The matrix product without BLAS, whose kernel (and so whose last bits) depends on the CPU.
    ``weights`` (T, K) and ``basis`` (K, N) are read as float64 (float32 values are exact in it);
    each sum is rounded to ``dtype`` once, at the end.
    """
    w = np.ascontiguousarray(weights, dtype=np.float64)
    b = np.ascontiguousarray(basis, dtype=np.float64) if basis.dtype != np.float32 else np.ascontiguousarray(basis)
    if w.ndim != 2 or b.ndim != 2 or w.shape[1] != b.shape[0] or w.shape[1] == 0:
        raise ValueError(f"weights (T, K) and basis (K, N) with K >= 1 expected, got {w.shape} and {b.shape}")
    single = np.dtype(dtype) == np.float32 and w.shape[1] <= 4
    out = np.empty((w.shape[0], b.shape[1]), np.float32 if single else np.float64)
    _weighted_sum(w, b, out, 8192)
    return out.astype(dtype, copy=False)


def combine(a: np.ndarray, coefficients: tuple[float, ...] | np.ndarray) -> np.ndarray:
    """``sum_c a[..., c] * coefficients[c]`` over the last axis, in order (no BLAS): e.g. RGB to luma."""
    a = np.asarray(a)
    c = np.asarray(coefficients, dtype=a.dtype if a.dtype.kind == "f" else np.float64)
    if a.ndim == 0 or a.shape[-1] != c.shape[0] or c.ndim != 1:
        raise ValueError(f"last axis of length {c.shape[0]} expected, got shape {a.shape}")
    out = a[..., 0] * c[0]
    for i in range(1, c.shape[0]):
        out = out + a[..., i] * c[i]
    return out
