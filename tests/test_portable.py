"""gevsim._portable: elementary functions with the same bits on every CPU.

Accuracy is measured against numpy's float128 (x87 80-bit, 64-bit mantissa) functions, which are
about 2000x finer than a double's ulp; special values are exact; the bits of every function on a
fixed set of arguments are pinned (``test_bits_are_pinned``), and ``tests/test_cpu_portability.py``
runs that pin again under other CPUs' code paths.
"""

from __future__ import annotations

import hashlib
import math
from decimal import Decimal, getcontext
from fractions import Fraction

import numpy as np
import pytest

from gevsim import _portable as pm

LD = np.longdouble
# 60 digits of pi (a published constant; checked against the double below).
PI_60 = Fraction("3.14159265358979323846264338327950288419716939937510582097494")


def max_ulps(got: np.ndarray, reference: np.ndarray) -> float:
    """Largest |got - reference| in ulps of the reference rounded to double."""
    r = reference.astype(np.float64)
    return float(np.max(np.abs((got.astype(LD) - reference) / np.spacing(np.abs(r)).astype(LD))))


RNG = np.random.default_rng(20261124)
CASES = {
    # name: (portable, float128 reference, arguments, ulp bound)
    "exp": (pm.exp, np.exp, RNG.uniform(-745.0, 709.7, 100_000), 1.0),
    "exp near 0": (pm.exp, np.exp, RNG.uniform(-1.0, 1.0, 100_000), 1.0),
    "expm1": (pm.expm1, np.expm1, np.r_[RNG.uniform(-1, 1, 50_000), RNG.uniform(-40, 700, 50_000),
                                        RNG.uniform(-1e-9, 1e-9, 1000)], 1.6),
    "log": (pm.log, np.log, np.exp(RNG.uniform(-744.0, 709.0, 100_000)), 1.0),
    "log near 1": (pm.log, np.log, RNG.uniform(0.5, 2.0, 100_000), 1.0),
    "log10": (pm.log10, np.log10, np.exp(RNG.uniform(-700.0, 700.0, 100_000)), 1.6),
    "sin": (pm.sin, np.sin, RNG.uniform(-4.0, 4.0, 100_000), 1.6),
    "cos": (pm.cos, np.cos, RNG.uniform(-4.0, 4.0, 100_000), 1.6),
    "sin large": (pm.sin, np.sin, RNG.uniform(-1.6e6, 1.6e6, 100_000), 2.6),
    "cos large": (pm.cos, np.cos, RNG.uniform(-1.6e6, 1.6e6, 100_000), 2.6),
    "tan": (pm.tan, np.tan, RNG.uniform(-1.5, 1.5, 100_000), 2.6),
    "atan": (pm.atan, np.arctan, np.r_[RNG.uniform(-3, 3, 50_000), np.exp(RNG.uniform(-30, 30, 50_000))], 2.6),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_accuracy_against_extended_precision(name):
    f, ref, x, bound = CASES[name]
    got = f(x)
    assert got.dtype == np.float64
    assert max_ulps(got, ref(x.astype(LD))) <= bound


def test_special_values():
    assert pm.exp(0.0) == 1.0 and pm.log(1.0) == 0.0 and pm.sin(0.0) == 0.0 and pm.cos(0.0) == 1.0
    assert pm.exp(np.inf) == np.inf and pm.exp(-np.inf) == 0.0 and pm.exp(710.0) == np.inf
    assert pm.exp(-746.0) == 0.0 and 0.0 < pm.exp(-745.0) < 1e-300  # subnormal result
    assert pm.log(0.0) == -np.inf and pm.log(np.inf) == np.inf
    assert np.isnan(pm.log(-1.0)) and np.isnan(pm.exp(np.nan)) and np.isnan(pm.sin(np.inf))
    assert pm.log(5e-324) == pytest.approx(-744.4400719213812, rel=1e-15)  # smallest subnormal
    assert pm.atan(np.inf) == pytest.approx(math.pi / 2, rel=1e-16) and pm.atan(-0.0) == 0.0
    assert pm.expm1(1e-300) == 1e-300 and pm.expm1(-50.0) == -1.0
    # exact at powers of ten (a pole count is ceil(log10(ratio)))
    assert [pm.log10(10.0**k) for k in range(23)] == list(range(23))


def test_constants_are_the_published_ones():
    """The split constants of ln 2 and pi/2 sum to the true values to well below a double's ulp."""
    getcontext().prec = 60
    ln2 = Fraction(Decimal(2).ln())
    assert abs(Fraction(pm._LN2_HI) + Fraction(pm._LN2_LO) - ln2) < Fraction(1, 2**85)
    assert Fraction(pm._LN2_HI).denominator <= 2**32  # k * LN2_HI is exact for |k| < 2**21
    pio2 = PI_60 / 2
    assert abs(Fraction(pm._PIO2_1) + Fraction(pm._PIO2_2) + Fraction(pm._PIO2_3) - pio2) < Fraction(1, 2**120)
    assert abs(Fraction(pm._PI_2) + Fraction(pm._PI_2_LO) - pio2) < Fraction(1, 2**105)
    assert pm._TWO_OVER_PI == float(1 / pio2)  # correctly rounded
    assert pm._TAN_PI_8 == float(Fraction(Decimal(2).sqrt()) - 1)  # tan(pi/8) = sqrt(2) - 1


def test_identities():
    x = RNG.uniform(-20, 20, 10_000)
    np.testing.assert_allclose(pm.sin(x) ** 2 + pm.cos(x) ** 2, 1.0, rtol=0, atol=4e-16)
    np.testing.assert_allclose(pm.log(pm.exp(x)), x, rtol=0, atol=4e-15)
    np.testing.assert_array_equal(pm.sin(-x), -pm.sin(x))  # odd by construction
    np.testing.assert_array_equal(pm.cos(-x), pm.cos(x))


@pytest.mark.parametrize("groups", [1, 2, 3, 4, 5, 9])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_weighted_sum_adds_in_group_order(groups, dtype):
    w = RNG.normal(size=(7, groups))
    b = RNG.normal(size=(groups, 20_000)).astype(dtype)  # more than one block per row
    expected = w[:, :1] * b[0].astype(np.float64)
    for k in range(1, groups):  # the same operations in the same order: the same bits
        expected = expected + w[:, k:k + 1] * b[k].astype(np.float64)
    out = pm.weighted_sum(w, b, dtype=dtype)
    assert out.dtype == dtype
    np.testing.assert_array_equal(out, expected.astype(dtype))


def test_weighted_sum_and_combine():
    w = RNG.normal(size=(7, 3))
    b = RNG.normal(size=(3, 50))
    rgb = RNG.random((4, 5, 3))
    np.testing.assert_array_equal(pm.combine(rgb, (0.2, 0.7, 0.1)),
                                  rgb[..., 0] * 0.2 + rgb[..., 1] * 0.7 + rgb[..., 2] * 0.1)
    with pytest.raises(ValueError, match="basis"):
        pm.weighted_sum(w, b[:2])
    with pytest.raises(ValueError, match="last axis"):
        pm.combine(rgb, (1.0, 2.0))


def portable_bits() -> str:
    """SHA-256 of every portable function on fixed arguments (including the reductions' edges)."""
    x = np.r_[np.linspace(-800.0, 800.0, 20_001), np.linspace(-1.0, 1.0, 4001), 1e-310, -1e-310, 0.0]
    pos = np.abs(x) + 1e-300
    h = hashlib.sha256()
    for f in (pm.exp, pm.expm1, pm.sin, pm.cos, pm.tan, pm.atan):
        h.update(f(x).tobytes())
    for f in (pm.log, pm.log10):
        h.update(f(pos).tobytes())
    w = (np.arange(12.0) - 5.5).reshape(4, 3) / 7.0
    h.update(pm.weighted_sum(w, np.linspace(0, 1, 3 * 70).reshape(3, 70) / 3.0).tobytes())
    return h.hexdigest()


def test_bits_are_pinned():
    """Computed once on an AMD EPYC with AVX-512 (numba on the host CPU); the same under
    NUMBA_CPU_NAME=generic/haswell, glibc without FMA and numpy without AVX-512
    (tests/test_cpu_portability.py)."""
    assert portable_bits() == PORTABLE_PIN


PORTABLE_PIN = "5df302f8e09230f854baa93f8b1c9bdac243d54326c3e33c6bcfd7b95f9baaf3"
