"""Flicker attribution with uncertainty: intervals from paired repeats, and a phase-locked estimator.

Two independent ways to say how much of an event stream lamp flicker causes:

1. **Paired counterfactuals** (DESIGN.md): each repeat r runs the scene with
   flicker and without, with the same seed (common random numbers), giving a
   difference ``d_r``. :func:`mean_interval` is the Student t interval of the
   mean of the ``d_r``; :func:`ratio_interval` is Fieller's interval for a
   ratio of two paired means (e.g. DVS over gradient flicker-induced rates)
   (Fieller, J. R. Stat. Soc. B 16, 1954; Franz, *Ratios: a short guide to
   confidence limits and proper use*, 2007). Never clamped: an interval that
   holds zero is reported as "not distinguishable from zero".
2. **Phase locking, no subtraction**: flicker is periodic with a known phase,
   so event times folded on the lamp period show a rate that depends on phase;
   events not caused by flicker do not. :func:`phase_locked_rate` estimates the
   RMS over the period of the event-rate modulation carried by the first
   harmonics (ev/px/s), bias-corrected for Poisson counting, with a bootstrap
   interval and a p-value against the phase-randomised null.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy import stats

from gevsim import _portable as pm


@dataclass(frozen=True)
class Interval:
    """A point estimate with its two-sided confidence interval."""

    estimate: float
    low: float
    high: float
    confidence: float
    n: int
    method: str

    @property
    def includes_zero(self) -> bool:
        return not (self.low > 0.0 or self.high < 0.0)

    def format(self, digits: int = 3) -> str:
        """``"12.3 [9.10, 15.5]"``; ``"not distinguishable from zero (-1.2 [-4.0, 1.6])"`` when it holds 0."""
        def g(v):
            return f"{v:.{digits}g}"
        text = f"{g(self.estimate)} [{g(self.low)}, {g(self.high)}]"
        return f"not distinguishable from zero ({text})" if self.includes_zero else text

    def as_dict(self) -> dict:
        return {"estimate": self.estimate, "low": self.low, "high": self.high, "confidence": self.confidence,
                "n": self.n, "method": self.method}


def _check_confidence(confidence: float) -> None:
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")


def mean_interval(values: ArrayLike, *, confidence: float = 0.95) -> Interval:
    """Student t interval of the mean of R independent paired differences (R >= 2).

    With one value the interval is unknown: (-inf, inf), method ``"t (1 repeat)"``.
    """
    _check_confidence(confidence)
    x = np.asarray(values, float).ravel()
    if x.size == 0 or not np.all(np.isfinite(x)):
        raise ValueError(f"mean_interval: need finite values, got {values!r}")
    mean = float(x.mean())
    if x.size < 2:
        return Interval(mean, -math.inf, math.inf, confidence, 1, "t (1 repeat)")
    se = float(x.std(ddof=1) / math.sqrt(x.size))
    half = float(stats.t.ppf(0.5 + confidence / 2.0, x.size - 1)) * se
    return Interval(mean, mean - half, mean + half, confidence, int(x.size), "t")


def ratio_interval(numerator: ArrayLike, denominator: ArrayLike, *, confidence: float = 0.95) -> Interval:
    """Fieller's interval for mean(numerator) / mean(denominator) from R paired repeats.

    The pairs may be correlated (same seeds): their covariance is used. When
    the denominator's mean is not distinguishable from zero at this level the
    set is unbounded and (-inf, inf) is returned (method ``"fieller (unbounded)"``).
    """
    _check_confidence(confidence)
    a = np.asarray(numerator, float).ravel()
    b = np.asarray(denominator, float).ravel()
    if a.shape != b.shape or a.size == 0 or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise ValueError("ratio_interval: numerator and denominator must be finite and paired (same length)")
    ma, mb = float(a.mean()), float(b.mean())
    ratio = ma / mb if mb != 0.0 else math.copysign(math.inf, ma) if ma else math.nan
    n = a.size
    if n < 2:
        return Interval(ratio, -math.inf, math.inf, confidence, 1, "fieller (1 repeat)")
    cov = np.cov(a, b, ddof=1) / n  # covariance of the two means
    vaa, vbb, vab = float(cov[0, 0]), float(cov[1, 1]), float(cov[0, 1])
    t = float(stats.t.ppf(0.5 + confidence / 2.0, n - 1))
    # Solve (ma - R mb)^2 = t^2 (vaa - 2 R vab + R^2 vbb) for R.
    qa = mb * mb - t * t * vbb
    qb = -2.0 * (ma * mb - t * t * vab)
    qc = ma * ma - t * t * vaa
    disc = qb * qb - 4.0 * qa * qc
    if qa <= 0.0 or disc < 0.0:
        return Interval(ratio, -math.inf, math.inf, confidence, n, "fieller (unbounded)")
    root = math.sqrt(disc)
    lo, hi = sorted(((-qb - root) / (2.0 * qa), (-qb + root) / (2.0 * qa)))
    return Interval(ratio, lo, hi, confidence, n, "fieller")


@dataclass(frozen=True)
class PhaseLocked:
    """Phase-locked modulation of an event stream's rate (ev/px/s)."""

    rms: Interval  # RMS over the lamp period of the rate modulation in the first harmonics
    # (M,) complex coefficients c_m of the rate, ev/px/s (r = mean + sum 2 Re c_m e^{2 pi i m phi})
    harmonics: np.ndarray
    mean_rate: float  # ev/px/s
    p_value: float  # against the phase-randomised null (no locking)
    events: int

    def as_dict(self) -> dict:
        return {"rms": self.rms.as_dict(), "mean_rate": self.mean_rate, "p_value": self.p_value,
                "events": self.events, "amplitude": [float(2 * abs(c)) for c in self.harmonics]}


#: Phase bins of a folded event stream: quantising phases to 1/512 of the period attenuates the
#: m-th harmonic's amplitude by sinc(m / 512), under 1e-4 for m <= 4 (the default harmonics).
PHASE_BINS = 512


def phase_histogram(t_s: ArrayLike, *, period_s: float, bins: int = PHASE_BINS) -> np.ndarray:
    """Event counts (int64, ``bins``) over the lamp phase [0, 1) of times ``t_s`` (s).

    Histograms of repeats of the same run add: fold each, sum, then call
    :func:`phase_locked_from_histogram` with the summed duration."""
    if not (period_s > 0 and math.isfinite(period_s)) or bins < 2:
        raise ValueError(f"phase_histogram: period_s must be a positive number and bins >= 2, got "
                         f"{period_s!r}, {bins!r}")
    t = np.asarray(t_s, float).ravel()
    index = np.floor(np.mod(t / period_s, 1.0) * bins).astype(np.int64)
    return np.bincount(np.minimum(index, bins - 1), minlength=bins).astype(np.int64)


def _coefficients(counts: np.ndarray, harmonics: int, scale: float) -> np.ndarray:
    """c_m = scale sum_b n_b exp(-2 pi i m phi_b) at bin centres, for one histogram (B,) or many (R, B)."""
    bins = counts.shape[-1]
    phi = (np.arange(bins) + 0.5) / bins
    angle = 2.0 * np.pi * phi[:, None] * np.arange(1, harmonics + 1)[None, :]  # (B, M)
    n = np.asarray(counts, dtype=np.float64)
    rows = n.reshape(-1, bins)
    re = pm.weighted_sum(rows, pm.cos(angle))
    im = pm.weighted_sum(rows, pm.sin(angle))
    return ((re - 1j * im) * scale).reshape(n.shape[:-1] + (harmonics,))


def _power(c: np.ndarray, n: np.ndarray | float, scale: float) -> np.ndarray:
    """Bias-corrected variance of the modulation, sum_m 2 (|c_m|^2 - N scale^2): a Poisson process of
    N uniform phases has E|c_m|^2 = N scale^2 for every m."""
    return np.sum(2.0 * (np.square(np.abs(c)) - np.asarray(n)[..., None] * (scale * scale)), axis=-1)


def _signed_root(p):
    return np.sign(p) * np.sqrt(np.abs(p))


def phase_locked_rate(t_s: ArrayLike, *, period_s: float, duration_s: float, n_pixels: int, harmonics: int = 4,
                      confidence: float = 0.95, n_boot: int = 400, seed: int = 0) -> PhaseLocked:
    """Rate modulation locked to a lamp of period ``period_s``, from event times ``t_s`` (s).

    The event rate per pixel as a function of lamp phase phi is written
    ``r(phi) = rbar + sum_m 2 Re(c_m exp(2 pi i m phi))``; with N events over
    ``duration_s`` and P pixels, ``c_m = sum_j exp(-2 pi i m phi_j) / (P T)``.
    The estimate is the RMS of the modulation over phi, ``sqrt(sum_m 2 |c_m|^2)``,
    from the first ``harmonics`` terms, with the Poisson bias ``N / (P T)^2``
    removed from each ``|c_m|^2`` (unbiased for the squared RMS; the square
    root of a negative estimate is reported as its negative). The interval is
    a percentile bootstrap over events (seeded, ``n_boot`` Poisson-bootstrap
    resamples; the replicates re-centred on the estimate, since resampling
    restores the Poisson term the estimate removes). The p-value is that of the
    phase-randomised null (uniform phases, as events that no lamp causes would
    have), from the Z^2_M test (Buccheri et al. 1983, A&A 128, 245): under it
    ``Z^2_M = 2 sum_m |c_m|^2 / (N scale^2)`` is chi-square with 2M degrees of
    freedom for large N, so ``p = chi2.sf(Z^2_M, 2M)`` (exact in its tail, where
    simulated nulls could not go below ``1 / (n_boot + 1)``).
    ``duration_s`` should hold whole periods. Phases are folded into
    :data:`PHASE_BINS` bins (:func:`phase_histogram`).
    """
    return phase_locked_from_histogram(phase_histogram(t_s, period_s=period_s), duration_s=duration_s,
                                       n_pixels=n_pixels, harmonics=harmonics, confidence=confidence,
                                       n_boot=n_boot, seed=seed)


def phase_locked_from_histogram(counts: ArrayLike, *, duration_s: float, n_pixels: int, harmonics: int = 4,
                                confidence: float = 0.95, n_boot: int = 400, seed: int = 0) -> PhaseLocked:
    """:func:`phase_locked_rate` from a phase histogram (:func:`phase_histogram`, or the sum of
    several repeats' histograms with ``duration_s`` their summed duration). The bootstrap
    resamples the N events multinomially over the bins; the null draws N uniform phases."""
    _check_confidence(confidence)
    counts = np.asarray(counts)
    if not (duration_s > 0 and n_pixels >= 1 and harmonics >= 1 and n_boot >= 1) or counts.ndim != 1:
        raise ValueError(f"phase_locked_rate: duration_s, n_pixels, harmonics and n_boot must be positive and "
                         f"counts one histogram, got {duration_s!r}, {n_pixels!r}, {harmonics!r}, {n_boot!r}")
    if np.any(counts < 0) or counts.size < 2 * harmonics + 1:
        raise ValueError(f"phase_locked_rate: need non-negative counts in at least {2 * harmonics + 1} bins")
    n = int(counts.sum())
    scale = 1.0 / (n_pixels * duration_s)
    c = _coefficients(counts.astype(float), harmonics, scale)
    power = float(_power(c, n, scale))
    rng = np.random.default_rng(seed)
    # Poisson bootstrap (each bin's count redrawn as Poisson of itself: resampling events with a random
    # total); each replicate's Poisson term uses its own total.
    boot_counts = rng.poisson(counts, size=(n_boot, counts.size)).astype(float)
    boot = _power(_coefficients(boot_counts, harmonics, scale), boot_counts.sum(axis=1), scale)
    # Resampling with replacement adds back the Poisson term that the estimate removes: re-centre the
    # replicates on the estimate (squared scale) before taking roots and percentiles.
    boot = _signed_root(boot - (boot.mean() - power))
    estimate = float(_signed_root(power))
    lo, hi = np.percentile(boot, [50 * (1 - confidence), 50 * (1 + confidence)])
    z2 = 2.0 * float(np.sum(np.square(np.abs(c)))) / (n * scale * scale) if n else 0.0
    p_value = float(stats.chi2.sf(z2, 2 * harmonics))
    rms = Interval(estimate, float(lo), float(hi), confidence, n, "bootstrap percentile")
    return PhaseLocked(rms=rms, harmonics=c, mean_rate=float(n * scale), p_value=p_value, events=n)
