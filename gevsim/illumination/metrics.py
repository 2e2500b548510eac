"""Flicker metrics of a waveform (IEEE Std 1789-2015, section 4 definitions).

``percent_flicker = 100 (max - min) / (max + min)`` and ``flicker_index`` =
area above the mean over total area, both over one period (over the table
span for a non-periodic :class:`~gevsim.illumination.Table`).
"""

from __future__ import annotations

import numpy as np

from gevsim._validate import integer

from .base import Waveform

__all__ = ["percent_flicker", "flicker_index", "modulation_spectrum"]

#: Default samples per period: PWM edges then cost at most ~1/65536 in area.
DEFAULT_SAMPLES = 2**16


def _one_period(waveform: Waveform, samples: int) -> tuple[np.ndarray, float]:
    """Midpoint samples of one reference span, and the span's mean."""
    if not isinstance(waveform, Waveform):
        raise TypeError(f"waveform={waveform!r} is not a Waveform")
    samples = integer(samples, "samples", low=2)
    a, b = waveform.reference_span()
    t = a + (np.arange(samples) + 0.5) * ((b - a) / samples)
    return waveform(t), waveform.mean_value


def percent_flicker(waveform: Waveform, *, samples: int = DEFAULT_SAMPLES) -> float:
    """Percent flicker (modulation depth x 100), IEEE Std 1789-2015.

    Uses the waveform's exact extrema where it provides them, otherwise
    ``samples`` midpoint samples of one period.
    """
    rng = waveform.value_range() if isinstance(waveform, Waveform) else None
    if rng is None:
        w, _ = _one_period(waveform, samples)
        rng = (float(w.min()), float(w.max()))
    lo, hi = rng
    return 0.0 if hi + lo == 0 else 100.0 * (hi - lo) / (hi + lo)


def flicker_index(waveform: Waveform, *, samples: int = DEFAULT_SAMPLES) -> float:
    """Flicker index: area above the mean divided by total area over one period.

    IEEE Std 1789-2015; 0 for steady light, ``1 - D`` for an ideal PWM of
    duty ``D``, ``1/pi`` for a full ``sin^2``. Midpoint rule on ``samples``.
    """
    w, mean = _one_period(waveform, samples)
    return float(np.mean(np.maximum(w - mean, 0.0)) / mean)


def modulation_spectrum(waveform: Waveform, *, harmonics: int = 10,
                        samples: int = DEFAULT_SAMPLES) -> np.ndarray:
    """Amplitudes of harmonics ``1..harmonics`` of the fundamental, relative to the mean.

    Harmonic ``n`` has frequency ``n / period_s``; a waveform ``1 + m sin(...)``
    gives ``[m, 0, ...]``. Computed by FFT of ``samples`` points of one period.
    """
    harmonics = integer(harmonics, "harmonics", low=1)
    if samples < 2 * harmonics + 2:
        raise ValueError(f"samples={samples!r} too few for harmonics={harmonics!r}")
    w, _ = _one_period(waveform, samples)
    spec = np.fft.rfft(w) / w.size
    return 2.0 * np.abs(spec[1:harmonics + 1]) / spec[0].real
