"""Logarithmic photoreceptor with light-dependent bandwidth and noise.

V = V0 + n U_T ln(I_ph + I_dark), low-pass filtered with a cutoff that grows
in proportion to photocurrent up to an amplifier-limited maximum (dim pixels
are slow). The update for a step of held photocurrent is the exact solution
(1 - exp(-dt/tau)), so results do not depend on dt for piecewise-constant
input; the optional second pole is also integrated exactly.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike

from gevsim import _portable as pm
from gevsim._finite import count_invalid
from gevsim.pixel import _kernels
from gevsim.pixel._cascade import separated_hz
from gevsim.pixel.mechanisms import NOISE_MECHANISMS, kernel_noise
from gevsim.pixel.noise import NoiseLaw, fixed_pattern
from gevsim.pixel.params import NoiseParams, PhotoreceptorParams
from gevsim.timebase import check_chunk


class Photoreceptor:
    """Stateful photoreceptor for an (H, W) array of pixels.

    Calling :meth:`process` on consecutive chunks of a sequence gives the same
    output, bit for bit, as one call on the whole sequence.

    Parameters
    ----------
    shape : (H, W).
    params, noise : the photoreceptor and noise parameters (see a sensor preset).
    rng : draws the fixed patterns, the key of the temporal noise and the noise's start.
    t0_s : start time; the first step ends at the first time given to :meth:`process`.
    cold_start : False (default): the noise starts stationary (a sensor that has been running:
        shot and read noise drawn from their stationary joint law through the output pole);
        True: the shot noise starts at zero (the behaviour before issue 22). Either way the
        filters start settled on the first sample's photocurrent.
    """

    def __init__(self, shape: Sequence[int], *, params: PhotoreceptorParams, noise: NoiseParams,
                 rng: np.random.Generator,
                 t0_s: float = 0.0, cold_start: bool = False):
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        if len(shape) != 2 or min(shape) < 1:
            raise ValueError(f"shape must be (H, W) with H, W >= 1, got {shape!r}")
        plan = kernel_noise(noise, params.volts_per_ln)  # every temporal mechanism's coefficients
        bandwidth = math.isfinite(params.cutoff_hz) or math.isfinite(params.max_cutoff_hz)
        if plan.shot_q > 0 and not bandwidth:
            raise ValueError("shot noise needs a finite photoreceptor bandwidth (its variance grows with it)")
        if plan.amp_ln2_hz > 0 and not bandwidth:
            raise ValueError("amplifier noise needs a finite photoreceptor bandwidth (its variance is "
                             "amplifier_noise_ln2_hz / f_c)")
        self.shape = tuple(int(s) for s in shape)
        self.params, self.noise = params, noise
        gain, dark = fixed_pattern(self.shape, noise, rng=rng, temperature_k=params.temperature_k)
        self.gain = gain.ravel().astype(np.float64)
        self.dark_a = dark.ravel().astype(np.float64)
        self.key = int(rng.integers(0, 2**64, dtype=np.uint64))  # of the 64-bit counter-based noise generator
        self.fn_hz, self.fn_var = plan.poles()
        n = self.gain.size
        self.fn = (np.sqrt(self.fn_var)[:, None] * rng.standard_normal((len(self.fn_hz), n))).astype(np.float64)
        self.n_read = plan.n_cascaded  # fn[0] is the read noise when 1
        self.start_z = rng.standard_normal((3, n))  # the noise's stationary start (drawn in either mode)
        self.cold_start = bool(cold_start)
        self.offset_ln = _output_patterns(noise, n, params.volts_per_ln, rng)
        self.shot_q, self.amp_ln2_hz = plan.shot_q, plan.amp_ln2_hz
        self.v1 = np.zeros(n)
        self.v2 = np.zeros(n)
        self.t_s = float(t0_s)
        self.step = 0
        self.started = False

    @property
    def volts_per_ln(self) -> float:
        return self.params.volts_per_ln

    def to_volts(self, v_ln: ArrayLike) -> np.ndarray:
        """Photoreceptor output in volts from ln units."""
        return self.params.v0_v + self.params.volts_per_ln * np.asarray(v_ln)

    def _bandwidth(self) -> tuple[float, float, float, float]:
        """The kernel's bandwidth arguments: (fc_ref (<= 0: no filter), i_ref, fc_max, f2 (0: none))."""
        p = self.params
        fc_ref = p.cutoff_hz if math.isfinite(p.cutoff_hz) else (-1.0 if not math.isfinite(p.max_cutoff_hz) else 1e300)
        fc_max = p.max_cutoff_hz if math.isfinite(p.max_cutoff_hz) else np.inf
        return fc_ref, p.cutoff_ref_photocurrent_a, fc_max, p.second_pole_hz or 0.0

    def steady_state(self, photocurrent_a: ArrayLike) -> np.ndarray:
        """Noise-free settled output (ln units) for a constant photocurrent (H, W)."""
        i = np.asarray(photocurrent_a, float).reshape(-1)
        return pm.log(i * self.gain + self.dark_a).reshape(self.shape)

    def settle(self, photocurrent_a: ArrayLike | Callable[[int, int], ArrayLike], dt_s: ArrayLike, *,
               chunk_steps: int | None = None) -> None:
        """Start at the periodic steady state of a light that repeats ``photocurrent_a`` (T, H, W),
        each sample held over the step ``dt_s`` (T,): a sensor that has been running under it.

        The noise-free filters are affine in their start, so one period run from three starts gives
        each pixel's map (v1, v2) -> (A v1 + c1, B v1 + C v2 + c2) and its fixed point, exactly (no
        warm-up to wait out, however slow the dim pixels). The noise then starts stationary unless
        ``cold_start``. Call before the first :meth:`process`.

        ``photocurrent_a`` may instead be a function ``(a, b)`` giving samples a .. b - 1 (b - a, H, W),
        asked for ``chunk_steps`` samples at a time (None: all at once), three times over: the period's
        photocurrent is then never held whole (issue 37: a 100 Hz lamp at 1280x720 is 3.7 GB of it).
        The result does not depend on the chunks.
        """
        if self.started:
            raise ValueError("settle() must come before the first process()")
        dt = np.asarray(dt_s, dtype=np.float64).reshape(-1)
        whole = None if callable(photocurrent_a) else photocurrent_a
        if whole is not None:  # every sample, read once here
            whole = np.ascontiguousarray(whole, dtype=np.float64).reshape(len(dt), -1)
        if not np.all(dt > 0):
            raise ValueError(f"settle needs photocurrent (T, {self.shape[0]}, {self.shape[1]}) and steps > 0")
        p = self.params
        n = self.gain.size
        size = len(dt) if chunk_steps is None else max(1, int(chunk_steps))

        def samples(a: int, b: int) -> np.ndarray:
            flat = whole[a:b] if whole is not None else np.ascontiguousarray(
                photocurrent_a(a, b), dtype=np.float64).reshape(b - a, -1)  # type: ignore[operator]
            if flat.shape != (b - a, n):
                raise ValueError(f"settle needs photocurrent (T, {self.shape[0]}, {self.shape[1]}) and steps > 0")
            if count_invalid(flat, nonnegative=True):
                raise ValueError("settle: photocurrent must be finite and >= 0")
            return flat

        def period(v1: np.ndarray, v2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            v1, v2 = v1.copy(), v2.copy()
            for a in range(0, len(dt), size):
                flat = samples(a, min(a + size, len(dt)))
                _kernels.photoreceptor(flat, dt[a:a + len(flat)], self.gain, self.dark_a, v1, v2, np.zeros((0, n)),
                                       np.zeros(0), np.zeros(0), np.uint64(self.key), 0, *self._bandwidth(), 0.0,
                                       0.0, 0, np.empty(flat.shape, np.float32))
            return v1, v2

        first = samples(0, 1)[0] * self.gain + self.dark_a
        u0 = pm.log(first)
        c1, c2 = period(u0, u0)
        a1, a2 = period(u0 + 1.0, u0)
        w1 = _fixed_point(c1 - u0, a1 - c1)  # fixed point, as a deviation from u0
        if p.second_pole_hz is not None:
            _, b2 = period(u0, u0 + 1.0)
            w2 = _fixed_point((a2 - c2) * w1 + (c2 - u0), b2 - c2)
        else:
            w2 = w1
        self.v1, self.v2 = u0 + w1, u0 + w2
        self.settled_current_a = first
        self.settled_ln = self.v2 + (self.offset_ln if self.offset_ln is not None else 0.0)  # noise-free output
        self._noise_free_start = (self.v1.copy(), self.v2.copy(), self.t_s)
        if not self.cold_start:
            self._stationary_noise(first, self.v1, self.v2, self.fn)
        self.started = True

    def _stationary_noise(self, itot: np.ndarray, v1: np.ndarray, v2: np.ndarray, fn: np.ndarray) -> None:
        """Add to the settled states v1 (photoreceptor) and v2 (output) a draw of the stationary
        shot noise at total photocurrent ``itot``, and to v2 the output pole's share of the read
        noise already in ``fn[0]`` (:mod:`gevsim.pixel._cascade`), in place."""
        p = self.params
        f_out = p.second_pole_hz
        beta = 2.0 * math.pi * f_out if f_out is not None else math.inf
        if self.shot_q > 0 or self.amp_ln2_hz > 0:
            fc = p.cutoff_at(itot)  # as the kernel: proportional to the total current, capped
            if f_out is not None:  # as the kernel: a pole within POLE_GAP of the output pole is moved to it
                fc = separated_hz(fc, f_out)
            var = self.shot_q * fc / itot + self.amp_ln2_hz / fc
            alpha = 2.0 * math.pi * fc
            xn = np.sqrt(var) * self.start_z[0]
            v1 += xn
            if f_out is not None:
                v2 += beta / (alpha + beta) * xn + np.sqrt(var * alpha * beta) / (alpha + beta) * self.start_z[1]
            else:
                v2 += xn
        if f_out is not None and self.n_read:
            a_r = 2.0 * math.pi * float(separated_hz(self.fn_hz[0], f_out))
            s = math.sqrt(self.fn_var[0])
            v2 += beta / (a_r + beta) * fn[0] + s * math.sqrt(a_r * beta) / (a_r + beta) * self.start_z[2]

    def noise_free_twin(self) -> Photoreceptor:
        """A copy that follows this photoreceptor's noise-free path: the same fixed patterns and response, every
        temporal noise off, in the noise-free states :meth:`settle` found. Take it right after :meth:`settle`
        and give it the same photocurrent: its output is then the mean of this one's given the light (the
        cascade is linear in its states), the noise-free signal a :class:`gevsim.events.bridge.Bridge` needs."""
        start = getattr(self, "_noise_free_start", None)
        if start is None or start[2] != self.t_s:
            raise RuntimeError("noise_free_twin: take it right after settle(), before the first process()")
        twin = copy.deepcopy(self)
        twin.shot_q = twin.amp_ln2_hz = 0.0
        twin.fn_var, twin.fn = np.zeros_like(self.fn_var), np.zeros_like(self.fn)
        twin.v1, twin.v2 = start[0].copy(), start[1].copy()
        return twin

    def noise_law(self) -> NoiseLaw | None:
        """The output noise's law at any photocurrent (:class:`gevsim.pixel.noise.NoiseLaw`); None without an
        output pole (a single pole's path has no crossing rate) or without a bandwidth."""
        fc_ref, i_ref, fc_max, f_out = self._bandwidth()
        if not f_out or fc_ref <= 0.0:
            return None
        beta = 2.0 * math.pi * f_out
        read_var, read_rate = 0.0, 1.0
        if self.n_read:
            read_rate = 2.0 * math.pi * float(separated_hz(self.fn_hz[0], f_out))
            read_var = float(self.fn_var[0]) * beta / (read_rate + beta)
        return NoiseLaw(float(self.shot_q), float(self.amp_ln2_hz), fc_ref / i_ref, fc_max, float(f_out), read_var,
                        read_rate)

    def noise_components(self, total_a: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray] | None:
        """The output's noise at total photocurrent ``total_a`` (default: the settled one) as
        :meth:`NoiseLaw.components <gevsim.pixel.noise.NoiseLaw.components>` gives it: (var, rate), each
        (K, pixels). None without an output pole."""
        law = self.noise_law()
        if law is None:
            return None
        return law.components(self.settled_current_a if total_a is None else total_a)

    def output_noise_law(self, lag_s: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The output noise's standard deviation (ln), Rice frequency (Hz) and correlation over ``lag_s`` per
        pixel, at the settled photocurrent: the level crossing rate of a level w is nu exp(-w^2 / 2 sigma^2)
        (Rice 1944). Each white noise through two poles (rates alpha, beta; :meth:`noise_components`) has
        variance v at the output, derivative variance v alpha beta and correlation
        (beta e^(-alpha tau) - alpha e^(-beta tau)) / (beta - alpha), so nu = (1 / 2 pi) sqrt(sum of
        derivative variances / sum of variances). The 1/f poles' OU terms add to sigma (and the correlation)
        only. None without an output pole (a single pole's path has no crossing rate) or before :meth:`settle`."""
        p = self.params
        if p.second_pole_hz is None or getattr(self, "settled_current_a", None) is None:
            return None
        beta = 2.0 * math.pi * p.second_pole_hz
        shape = np.shape(self.settled_current_a)
        parts = self.noise_components()
        assert parts is not None
        var = np.zeros(shape)
        dvar, cov = np.zeros(shape), np.zeros(shape)
        for v, alpha in zip(*parts, strict=True):
            v, alpha = v.reshape(shape), alpha.reshape(shape)
            var = var + v
            dvar = dvar + v * alpha * beta
            decay_a, decay_b = pm.exp(np.asarray(-alpha * lag_s, float)), pm.exp(np.asarray(-beta * lag_s, float))
            cov = cov + v * (beta * decay_a - alpha * decay_b) / (beta - alpha)
        for k in range(self.n_read, len(self.fn_hz)):
            var = var + self.fn_var[k]
            cov = cov + self.fn_var[k] * pm.exp(np.asarray(-2.0 * math.pi * self.fn_hz[k] * lag_s, float))
        safe = np.maximum(var, 1e-300)
        return np.sqrt(var), np.sqrt(dvar / safe) / (2.0 * math.pi), cov / safe

    def process(self, photocurrent_a: ArrayLike, t_s: ArrayLike) -> np.ndarray:
        """Advance over T steps and return the output (T, H, W) float32, in ln units.

        Parameters
        ----------
        photocurrent_a : (T, H, W) photocurrent; sample k is held from the end of
            the previous step to ``t_s[k]``.
        t_s : (T,) strictly increasing end times of the steps, after the current time.
        """
        current, t, prev = check_chunk(photocurrent_a, t_s, shape=self.shape, name="photocurrent", after=self.t_s)
        if len(t) == 0:
            return np.zeros((0,) + self.shape, np.float32)
        dt = t - prev
        flat = current.reshape(len(t), -1)
        v1, v2, fn = self.v1.copy(), self.v2.copy(), self.fn.copy()
        if not self.started:
            first = flat[0].astype(np.float64) * self.gain + self.dark_a
            if np.all(np.isfinite(first)) and np.all(first > 0):  # else the check below reports them
                v1 = pm.log(first)
                v2 = v1.copy()
                if not self.cold_start:
                    self._stationary_noise(first, v1, v2, fn)
        bad = count_invalid(flat, nonnegative=True)
        if not bad and np.any(self.dark_a <= 0):
            dark_free = self.dark_a <= 0
            bad = int(np.count_nonzero(flat[:, dark_free] * self.gain[dark_free] <= 0))
        if bad:
            raise ValueError(f"photocurrent must be finite and >= 0 (> 0 where the dark current is 0): "
                             f"{bad} of {flat.size} values are not")
        out = np.empty(flat.shape, np.float32)
        _kernels.photoreceptor(
            flat, dt, self.gain, self.dark_a, v1, v2, fn, self.fn_hz, self.fn_var, np.uint64(self.key), self.step,
            *self._bandwidth(), self.shot_q, self.amp_ln2_hz, self.n_read, out,
        )
        if self.offset_ln is not None:  # the DC offsets pass no filter: they are constant
            out += self.offset_ln
        self.v1, self.v2, self.fn = v1, v2, fn
        self.t_s = float(t[-1])
        self.step += len(t)
        self.started = True
        return out.reshape((len(t),) + self.shape)


def _output_patterns(noise: NoiseParams, n: int, volts_per_ln: float,
                     rng: np.random.Generator) -> np.ndarray | None:
    """The sum (ln, float32) of the fixed patterns that the mechanisms on add to the output (the DC
    offsets), or None. Drawn after everything else, each only when on, so that a preset without one
    draws the same numbers as before the mechanism existed."""
    total = None
    for mechanism in NOISE_MECHANISMS.values():
        if mechanism.pattern is not None and mechanism.table == "noise" and mechanism.is_on(noise):
            drawn = mechanism.pattern(noise, n, volts_per_ln, rng)
            total = drawn if total is None else total + drawn
    return total


def _fixed_point(shift: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """x = shift + gain x: shift / (1 - gain). A pole so slow that one period does not move it in double
    precision (gain rounds to 1: a dark current of ~1e-26 A) keeps its start (x = 0), not 0 / 0 = NaN."""
    den = 1.0 - gain
    return np.divide(shift, den, out=np.zeros_like(shift), where=den != 0)
