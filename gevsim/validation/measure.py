"""Measurements of a sensor preset on uniform static light, as a test bench would make them.

Each function runs gevsim's own pixel and event models (no shortcut formulas) on a small uniform
array under D65 light at a stated *chip* (focal-plane) illuminance and returns what a measurement
would report, with its uncertainty.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from gevsim.events import BrightnessEmulator
from gevsim.pixel import Photoreceptor
from gevsim.pixel.noise import coarsest_step_s
from gevsim.pixel.presets import SensorPreset, lux_to_photocurrent_a

#: Two-sided 95 % normal quantile.
Z95 = 1.959963984540054


@dataclass(frozen=True)
class Rate:
    """An event rate (ev/px/s) with its 95 % interval [low, high] (never below 0)."""

    value: float
    low: float
    high: float

    def __str__(self) -> str:
        return f"{self.value:.3g} [{self.low:.3g}, {self.high:.3g}]"


def rate_interval(counts: np.ndarray, duration_s: float) -> Rate:
    """Mean events per pixel per second and its 95 % interval from per-pixel counts: the normal
    interval of the mean over pixels (pixels differ by their fixed patterns), at least as wide as
    the Poisson interval of the total (Wilson-like, 1.96 sqrt(N)); with no event at all, [0, 3 / (n T)]
    (the rule of three)."""
    c = np.asarray(counts, float).ravel()
    n, total = c.size, float(c.sum())
    if total == 0:
        return Rate(0.0, 0.0, 3.0 / (n * duration_s))
    mean = total / (n * duration_s)
    se_pixels = float(np.std(c, ddof=1)) / math.sqrt(n) / duration_s if n > 1 else 0.0
    se_poisson = math.sqrt(total) / (n * duration_s)
    se = max(se_pixels, se_poisson)
    return Rate(mean, max(mean - Z95 * se, 0.0), mean + Z95 * se)


def photocurrent_a(preset: SensorPreset, chip_lux: float) -> float:
    """One pixel's photocurrent (A) at a D65 chip illuminance."""
    return chip_lux * lux_to_photocurrent_a(1.0, pixel_pitch_m=preset.pixel_pitch_m, fill_factor=preset.fill_factor,
                                            qe=preset.qe)


def default_step_s(preset: SensorPreset, chip_lux: float) -> float:
    """The step the driver would take: the coarsest at which noise-event rates converge, at most 20 us."""
    step = coarsest_step_s(preset.photoreceptor, preset.noise, photocurrent_a(preset, chip_lux))
    return min(2e-5, step) if step is not None else 2e-5


def running_sensor(preset: SensorPreset, shape: tuple[int, int], seed: int) -> tuple[Photoreceptor, BrightnessEmulator]:
    """The preset's photoreceptor and DVS over ``shape`` pixels, seeded from ``seed`` (start them with
    :func:`start_running` before the first chunk: a sensor that has been running)."""
    seeds = np.random.SeedSequence(seed).spawn(2)
    pr = Photoreceptor(shape, params=preset.photoreceptor, noise=preset.noise, rng=np.random.default_rng(seeds[0]))
    dvs = BrightnessEmulator(shape, preset.events, rng=np.random.default_rng(seeds[1]),
                             temperature_k=preset.photoreceptor.temperature_k)
    return pr, dvs


def start_running(pr: Photoreceptor, dvs: BrightnessEmulator, light: np.ndarray, step_s: float, *,
                  burn_in_s: float | None = None) -> float:
    """Start a bench as the driver starts a run (issue 34): the photoreceptor settled on ``light`` (T, H, W),
    one period of it held over steps of ``step_s`` (T = 1: constant light), each DVS level drawn from its
    stationary law given the noise, then ``burn_in_s`` (default: the driver's, rounded up to whole periods
    of ``light``) of the chain on that light, its events discarded. Returns the time the burn-in ended,
    after which the bench's own steps follow."""
    from gevsim.emulation.config import BURN_IN_S
    from gevsim.emulation.start import start_levels

    period = len(light)
    pr.settle(light, np.full(period, step_s))
    start_levels(pr, [dvs])
    span = BURN_IN_S if burn_in_s is None else float(burn_in_s)
    n = int(math.ceil(span / (period * step_s) - 1e-9)) * period
    if n:
        t = step_s * np.arange(1, n + 1)
        dvs.process(pr.process(np.tile(light, (n // period, 1, 1)), t), t)
    return n * step_s


def pixel_counts(events: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Events per pixel (flattened row-major)."""
    return np.bincount(events["y"].astype(np.int64) * shape[1] + events["x"], minlength=shape[0] * shape[1])


@dataclass(frozen=True)
class Counts:
    """Per-pixel DVS event counts (flattened row-major) of a run of ``span_s`` seconds."""

    on: np.ndarray
    off: np.ndarray
    span_s: float

    def rates(self) -> tuple[Rate, Rate]:
        """(ON, OFF) in ev/px/s with their 95 % intervals."""
        return rate_interval(self.on, self.span_s), rate_interval(self.off, self.span_s)


def background_counts(preset: SensorPreset, chip_lux: float, *, shape: tuple[int, int] = (32, 32),
                      duration_s: float = 10.0, seed: int = 0, step_s: float | None = None,
                      chunk_steps: int = 5000) -> Counts:
    """Per-pixel DVS background events (ON, OFF) under constant uniform light: a sensor that has
    been running (:func:`start_running`: settled photoreceptor, stationary noise and DVS levels, burnt in)."""
    step = default_step_s(preset, chip_lux) if step_s is None else float(step_s)
    n = int(math.ceil(duration_s / step))
    pr, dvs = running_sensor(preset, shape, seed)
    level = np.full((1,) + shape, photocurrent_a(preset, chip_lux))
    t0 = start_running(pr, dvs, level, step)
    on = np.zeros(shape[0] * shape[1], np.int64)
    off = np.zeros_like(on)
    for a in range(0, n, chunk_steps):
        t = t0 + step * np.arange(a + 1, min(a + chunk_steps, n) + 1)
        ev = dvs.process(pr.process(np.broadcast_to(level, (len(t),) + shape), t), t)
        on += pixel_counts(ev[ev["p"]], shape)
        off += pixel_counts(ev[~ev["p"]], shape)
    return Counts(on, off, n * step)


def background_activity(preset: SensorPreset, chip_lux: float, *, shape: tuple[int, int] = (32, 32),
                        duration_s: float = 10.0, seed: int = 0, step_s: float | None = None,
                        chunk_steps: int = 5000) -> tuple[Rate, Rate]:
    """DVS background activity (ON, OFF) in ev/px/s under constant uniform light: a sensor that has
    been running (:func:`background_counts`)."""
    return background_counts(preset, chip_lux, shape=shape, duration_s=duration_s, seed=seed, step_s=step_s,
                             chunk_steps=chunk_steps).rates()


def intrinsic_spread(counts: np.ndarray) -> float:
    """The pixel-to-pixel coefficient of variation of the event rate, with the Poisson scatter of
    the counts taken out: sqrt(var(n) - mean(n)) / mean(n) (0 where the counts vary no more than
    Poisson counts would; nan with no event). Comparable between runs of different lengths."""
    c = np.asarray(counts, float).ravel()
    m = float(c.mean())
    if m <= 0 or c.size < 2:
        return math.nan
    return math.sqrt(max(float(np.var(c, ddof=1)) - m, 0.0)) / m


def intrinsic_correlation(a: np.ndarray, b: np.ndarray) -> float:
    """The pixel-to-pixel correlation of two event rates (ON and OFF of the same pixels) with the
    Poisson scatter of the counts taken out of the variances (it is independent between the two, so
    the covariance keeps): cov(a, b) / sqrt((var a - mean a) (var b - mean b)), clipped to [-1, 1];
    nan when either has no spread beyond Poisson."""
    x, y = np.asarray(a, float).ravel(), np.asarray(b, float).ravel()
    va, vb = float(np.var(x, ddof=1)) - float(x.mean()), float(np.var(y, ddof=1)) - float(y.mean())
    if va <= 0 or vb <= 0:
        return math.nan
    return max(-1.0, min(1.0, float(np.cov(x, y)[0, 1]) / math.sqrt(va * vb)))


def _ideal_photoreceptor(preset: SensorPreset, shape: tuple[int, int] = (1, 1)) -> Photoreceptor:
    """The preset's photoreceptor without noise or fixed patterns (a bench measurement averages them out)."""
    ideal = preset.ideal()
    return Photoreceptor(shape, params=ideal.photoreceptor, noise=ideal.noise, rng=np.random.default_rng(0))


def gain_at(preset: SensorPreset, chip_lux: float, frequency_hz: float, *, depth: float = 0.01) -> float:
    """Small-signal gain of the noise-free pixel output (photoreceptor and output pole) at one
    frequency: a ``depth`` sinusoidal modulation of the photocurrent, run 12 periods from the settled
    state, the output's amplitude over the last 4 fitted against the input's ln-amplitude."""
    pr = _ideal_photoreceptor(preset)
    i0 = photocurrent_a(preset, chip_lux)
    per = 1.0 / frequency_hz
    n = 2400
    dt = 12.0 * per / n
    t = dt * np.arange(1, n + 1)
    from gevsim import _portable as pm

    mid = t - 0.5 * dt
    cur = i0 * (1.0 + depth * pm.sin(2.0 * math.pi * frequency_hz * mid))
    pr.settle(np.full((1, 1, 1), i0), np.array([dt]))
    v = pr.process(cur.reshape(n, 1, 1), t).reshape(n).astype(np.float64)
    tail = slice(n - n // 3, n)  # the last 4 whole periods: sin and cos are orthogonal there
    w = 2.0 * math.pi * frequency_hz * mid[tail]
    sin, cos = pm.sin(w), pm.cos(w)

    def amplitude(x: np.ndarray) -> float:
        a, b = float(np.sum(x * sin)), float(np.sum(x * cos))
        return math.sqrt(a * a + b * b)

    # The reference is the same projection of the input's ln (with the dark current, which dilutes the
    # modulation of a dim pixel's total current): the gain is the filters' alone.
    dark = float(pr.dark_a[0])
    return amplitude(v[tail] - float(np.mean(v[tail]))) / amplitude(pm.log((cur[tail] + dark) / (i0 + dark)))


def cutoff_hz(preset: SensorPreset, chip_lux: float, *, tolerance: float = 0.005) -> float:
    """The measured -3 dB frequency (gain 1/sqrt 2) of the noise-free pixel output at a chip
    illuminance, by bisection in log frequency to ``tolerance`` relative."""
    lo, hi = 1e-3, 1e6
    target = 1.0 / math.sqrt(2.0)
    while hi / lo > 1.0 + tolerance:
        mid = math.sqrt(lo * hi)
        if gain_at(preset, chip_lux, mid) > target:
            lo = mid
        else:
            hi = mid
    return math.sqrt(lo * hi)


def step_latency_s(preset: SensorPreset, chip_lux: float, *, contrast_ln: float = 1.0) -> float:
    """Latency of the first ON event after a step of ``contrast_ln`` in ln photocurrent (L08's
    measurement: a flashed LED), noise-free, with nominal thresholds: the photoreceptor's and output
    pole's delay to the threshold plus the readout's fixed latency (its jitter's mean is ~0)."""
    ideal = preset.ideal()
    pr = _ideal_photoreceptor(preset)
    dvs = BrightnessEmulator((1, 1), ideal.events, rng=np.random.default_rng(0), cold_start=True)
    i0 = photocurrent_a(preset, chip_lux)
    fc = float(preset.photoreceptor.cutoff_at(i0 + preset.noise.dark_current_a))
    dt = min(0.5e-6, 0.002 / fc)
    n = int(math.ceil(20.0 / (2.0 * math.pi * fc) / dt)) + 2
    from gevsim import _portable as pm

    level = np.full((1, 1, 1), i0)
    pr.settle(level, np.array([dt]))
    t = dt * np.arange(1, n + 1)
    cur = np.full(n, i0 * float(pm.exp(contrast_ln)))
    cur[0] = i0  # the first sample sets the memorised level
    chunk = 20000
    for a in range(0, n, chunk):
        tt = t[a:a + chunk]
        ev = dvs.process(pr.process(cur[a:a + chunk].reshape(-1, 1, 1), tt), tt)
        on = ev[ev["p"]]
        if len(on):
            return float(on["t"][0]) * 1e-6 - float(t[0]) + preset.readout.latency_s
    return math.inf


def sinusoid_events_per_cycle(preset: SensorPreset, chip_lux: float, frequency_hz: float, *,
                              amplitude_ln: float = 0.5, threshold_ln: float = 0.05, cycles: int = 12,
                              skip: int = 2, per_cycle: int = 400) -> tuple[float, float]:
    """(ON, OFF) events per cycle of a sinusoid of ``amplitude_ln`` in ln photocurrent around a chip
    illuminance, on the noise-free pixel with ``threshold_ln`` thresholds, no refractory period and no
    leak (the analog chain's passband, as issue 34 states it: a pixel passing the sinusoid whole gives
    2 amplitude / threshold events per polarity per cycle, one at -3 dB 1 / sqrt 2 of that). The
    photoreceptor starts settled on the periodic light; the first ``skip`` cycles are not counted."""
    import dataclasses

    from gevsim import _portable as pm

    ideal = preset.ideal()
    events = dataclasses.replace(ideal.events, threshold_on_ln=threshold_ln, threshold_off_ln=threshold_ln,
                                 refractory_s=0.0)
    pr = _ideal_photoreceptor(preset)
    dvs = BrightnessEmulator((1, 1), events, rng=np.random.default_rng(1), light_leak=False)
    dt = 1.0 / (frequency_hz * per_cycle)
    n = cycles * per_cycle
    t = dt * np.arange(1, n + 1)
    phase = 2.0 * math.pi * frequency_hz * (t - 0.5 * dt)
    cur = photocurrent_a(preset, chip_lux) * pm.exp(amplitude_ln * pm.sin(phase))
    pr.settle(cur[:per_cycle].reshape(per_cycle, 1, 1), np.full(per_cycle, dt))
    ev = dvs.process(pr.process(cur.reshape(n, 1, 1), t), t)
    counted = ev[ev["t"] >= 1e6 * skip / frequency_hz]
    k = cycles - skip
    return float(np.count_nonzero(counted["p"])) / k, float(np.count_nonzero(~counted["p"])) / k
