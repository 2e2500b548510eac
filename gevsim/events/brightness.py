"""Brightness events (DVS): temporal contrast of the photoreceptor output.

Per pixel a memorised level; an ON (OFF) event when the signal rises (falls)
by the ON (OFF) threshold from it. Thresholds carry per-pixel Gaussian
mismatch; after an event the change amplifier is held in reset for the refractory
period and released with a reset error; several events may occur in one step,
and timestamps are the linearly interpolated crossing times inside the step
(Lichtsteiner, Posch & Delbruck 2008). Leak events come from the memorised
level drifting down at ``leak_rate_hz`` thresholds per second (with per-pixel
spread), as in v2e (Hu, Liu & Delbruck 2021).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from gevsim import _portable as pm
from gevsim.events import _bridge_dvs, _kernels
from gevsim.events._runner import EventBlocks, SampledSignal
from gevsim.events.bridge import Bridge
from gevsim.events.types import BRIGHTNESS_DTYPE, empty
from gevsim.pixel.params import REFERENCE_TEMPERATURE_K, EventParams, thermal_factor


def per_pixel_thresholds(shape: Sequence[int], params: EventParams, *,
                         rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """ON and OFF thresholds (ln units) with independent Gaussian mismatch, floored at 5 % of nominal."""
    sigma = params.threshold_mismatch_ln
    on = params.threshold_on_ln + sigma * rng.standard_normal(shape)
    off = params.threshold_off_ln + sigma * rng.standard_normal(shape)
    return np.maximum(on, 0.05 * params.threshold_on_ln), np.maximum(off, 0.05 * params.threshold_off_ln)


def leak_rates(shape: Sequence[int], params: EventParams, *, rng: np.random.Generator,
               temperature_k: float = REFERENCE_TEMPERATURE_K) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel leak event rates: (dark rate in Hz, rate per ampere of photocurrent in Hz/A).

    Each pixel's leak is its reset switch's junction leakage: a lognormal factor with mean 1 and
    relative sigma ``leak_rate_spread`` (a clipped normal left 2.3 % of pixels at 0 for a spread of
    0.5) times ``leak_rate_hz`` (doubling every ``leak_doubling_k`` above the reference temperature)
    in the dark and ``leak_light_hz_per_a`` for the parasitic photocurrent."""
    z = rng.standard_normal(shape)
    sigma = math.sqrt(float(pm.log(1.0 + params.leak_rate_spread * params.leak_rate_spread)))
    factor = pm.exp(sigma * z - 0.5 * sigma * sigma)
    dark_hz = params.leak_rate_hz * thermal_factor(temperature_k, params.leak_doubling_k)
    return dark_hz * factor, params.leak_light_hz_per_a * factor


class BrightnessEmulator:
    """DVS emulator over an (H, W) pixel array; state is kept across chunks.

    Parameters
    ----------
    shape : (H, W).
    params : thresholds, mismatch, refractory period, reset noise and leak (a preset's ``events``).
    rng : draws the fixed patterns (threshold mismatch, leak rates), the leak phases and the
        key of the reset noise.
    cold_start : False (default): a sensor that has been running, each leaking pixel's leak
        accumulator at a uniformly random phase (its level between 0 and one ON threshold below
        the first sample), so leak events come at their steady rate from the start. True: every
        level starts at the first sample (no leak event before 1 / leak rate).
    temperature_k : the sensor's temperature (scales the dark leak, see :func:`leak_rates`).
    light_leak : the signal is the log photocurrent, so the leak may grow with exp(signal)
        (``leak_light_hz_per_a``); False where the signal is something else (a centre-surround difference).
    """

    dtype = BRIGHTNESS_DTYPE

    def __init__(self, shape: Sequence[int], params: EventParams, *, rng: np.random.Generator,
                 cold_start: bool = False, temperature_k: float = REFERENCE_TEMPERATURE_K, light_leak: bool = True):
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        self.clock = SampledSignal(shape)
        self.shape = self.clock.shape
        self.params = params
        on, off = per_pixel_thresholds(self.shape, params, rng=rng)
        self.threshold_on_ln = on.ravel()
        self.threshold_off_ln = off.ravel()
        dark_hz, light_hz_per_a = leak_rates(self.shape, params, rng=rng, temperature_k=temperature_k)
        self.leak_ln_per_s = dark_hz.ravel() * self.threshold_on_ln
        lit = light_leak and params.leak_light_hz_per_a > 0
        self.leak_light = light_hz_per_a.ravel() * self.threshold_on_ln if lit else np.zeros(0)
        n = self.threshold_on_ln.size
        phase = rng.random(n)  # drawn in either mode, so that the key below does not depend on it
        leaks = (self.leak_ln_per_s > 0.0) | lit
        self.leak_phase = np.zeros(n) if cold_start else np.where(leaks, phase, 0.0)
        self.reset_key = np.uint64(rng.integers(0, 2**63, dtype=np.int64))
        self.start_ref: np.ndarray | None = None  # levels at the first sample, from start_from_noise
        self.start_seed = int(rng.integers(0, 2**63, dtype=np.int64))  # keys start_from_noise's draws
        self.ref = np.zeros(n)
        self.v_prev = np.zeros(n)
        self.mu_prev: np.ndarray | None = None  # the noise-free signal at the last sample (bridged steps only)
        # keys the crossing rule's draws (a Weyl step from the reset key: no draw of rng, so nothing else moves)
        self.bridge_key = np.uint64((int(self.reset_key) + 0x9E3779B97F4A7C15) % 2**64)
        self.last_t = np.full(n, -np.inf)
        self.count = np.zeros(n, np.int64)
        self._px_y, self._px_x = (a.ravel().astype(np.int16) for a in np.indices(self.shape))
        self.blocks = EventBlocks((n + _kernels.BLOCK - 1) // _kernels.BLOCK, dtype=self.dtype,
                                  first_per_step=_kernels.BLOCK / 8, min_free=_kernels.MAX_EVENTS_PER_STEP)

    def start_from_noise(self, sigma_ln: np.ndarray, crossings_hz: np.ndarray, correlation: np.ndarray,
                         signal_ln: np.ndarray) -> None:
        """Draw each pixel's start level from its stationary law given its noise (standard deviation
        ``sigma_ln``, Rice frequency ``crossings_hz``, ``correlation`` over the refractory period), its leak
        and its thresholds
        (:func:`gevsim.events.stationary.draw_levels`), in place of the uniform leak phase.
        ``signal_ln``: the settled noise-free signal (the levels are drawn about it, not about the first
        noisy sample, which would add that sample's noise to every level; the light leak grows with exp of it)."""
        from gevsim.events.stationary import draw_levels

        n = self.threshold_on_ln.size
        drift = self.leak_ln_per_s.copy()
        if self.leak_light.size:
            drift += self.leak_light * pm.exp(np.asarray(signal_ln, float).reshape(-1))
        uniform = np.random.default_rng(self.start_seed).random(n)
        u = np.empty(n)
        draw_levels(self.threshold_on_ln, self.threshold_off_ln, np.asarray(sigma_ln, float).reshape(-1),
                    np.asarray(crossings_hz, float).reshape(-1), np.asarray(correlation, float).reshape(-1),
                    drift, float(self.params.reset_noise_ln), uniform, u)
        self.start_ref = np.asarray(signal_ln, float).reshape(-1) + u

    def process(self, signal: ArrayLike, t_s: ArrayLike, *, bridge: Bridge | None = None) -> np.ndarray:
        """Events (sorted by time) from samples ``signal`` (T, H, W) in ln units at times ``t_s`` (T,).

        The signal is linear between samples; the very first sample only sets the memorised levels. With
        ``bridge`` (:class:`gevsim.events.bridge.Bridge`: the noise-free signal at the same samples, the
        photocurrent over each step and the noise law), a pixel quiet at both samples of a step may also cross a
        level in between, with the probability :mod:`gevsim.events.bridge` gives (long steps). The first
        bridged step after steps without it takes the noise at its first sample as 0.
        """
        v, t_start, t_end, first = self.clock.steps(signal, t_s, name="signal")
        if len(t_end) == 0:
            return empty(self.dtype)
        ref, v_prev, last_t, count = self.ref.copy(), self.v_prev.copy(), self.last_t.copy(), self.count.copy()
        if first:
            v_prev = v[0].reshape(-1).astype(np.float64)
            ref = v_prev - self.leak_phase * self.threshold_on_ln if self.start_ref is None else self.start_ref.copy()
        flat = v[1:] if first else v
        t_start, t_end = (t_start[1:], t_end[1:]) if first else (t_start, t_end)
        flat = flat.reshape(len(t_end), self.shape[0] * self.shape[1])
        p = self.params
        head = (ref, v_prev, last_t, count, self.threshold_on_ln, self.threshold_off_ln, self.leak_ln_per_s,
                self.leak_light, p.refractory_s, p.reset_noise_ln, self.reset_key)
        if bridge is None:
            def kernel(a, b, us_end, buf_t, buf_x, buf_y, buf_p, buf_axis, region, order):
                _kernels.brightness(flat[a:b], t_start[a:b], t_end[a:b], us_end, *head, self._px_x, self._px_y,
                                    buf_t, buf_x, buf_y, buf_p, region, order)
            events = self.blocks.collect(kernel, t_start, t_end)
            self.mu_prev = None  # unknown after steps without a bridge: the next bridged step takes the noise as 0
        else:
            mu, itot = bridge.arrays(v.shape, first)
            mu_prev = mu[0].astype(np.float64) if first else (v_prev if self.mu_prev is None else self.mu_prev).copy()
            mu = mu[1:] if first else mu
            law = bridge.law.as_tuple()

            def kernel(a, b, us_end, buf_t, buf_x, buf_y, buf_p, buf_axis, region, order):
                r, vp, lt, c, *rest = head
                _bridge_dvs.brightness_bridged(flat[a:b], mu[a:b], itot[a:b], t_start[a:b], t_end[a:b], us_end, r,
                                               vp, mu_prev, lt, c, *rest, self.bridge_key, law, self._px_x,
                                               self._px_y, buf_t, buf_x, buf_y, buf_p, region, order)
            events = self.blocks.collect(kernel, t_start, t_end)
            self.mu_prev = mu_prev
        self.ref, self.v_prev, self.last_t, self.count = ref, v_prev, last_t, count
        self.clock.t_s = float(np.asarray(t_s, float).reshape(-1)[-1])
        return events
