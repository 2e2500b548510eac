"""Logarithmic photoreceptor with light-dependent bandwidth and noise.

V = V0 + n U_T ln(I_ph + I_dark), low-pass filtered with a cutoff that grows
in proportion to photocurrent up to an amplifier-limited maximum (dim pixels
are slow). The update for a step of held photocurrent is the exact solution
(1 - exp(-dt/tau)), so results do not depend on dt for piecewise-constant
input; the optional second pole is also integrated exactly.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike
from scipy.constants import elementary_charge

from gevsim import _portable as pm
from gevsim._finite import count_invalid
from gevsim.pixel import _kernels
from gevsim.pixel.noise import fixed_pattern, output_noise_poles
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
    rng : draws the fixed patterns and the key of the temporal noise.
    t0_s : start time; the first step ends at the first time given to :meth:`process`.
    """

    def __init__(self, shape: Sequence[int], *, params: PhotoreceptorParams, noise: NoiseParams,
                 rng: np.random.Generator,
                 t0_s: float = 0.0):
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        if len(shape) != 2 or min(shape) < 1:
            raise ValueError(f"shape must be (H, W) with H, W >= 1, got {shape!r}")
        bandwidth = math.isfinite(params.cutoff_hz) or math.isfinite(params.max_cutoff_hz)
        if noise.shot_noise and not bandwidth:
            raise ValueError("shot noise needs a finite photoreceptor bandwidth (its variance grows with it)")
        self.shape = tuple(int(s) for s in shape)
        self.params, self.noise = params, noise
        gain, dark = fixed_pattern(self.shape, noise, rng=rng)
        self.gain = gain.ravel().astype(np.float64)
        self.dark_a = dark.ravel().astype(np.float64)
        self.key = int(rng.integers(0, 2**64, dtype=np.uint64))  # of the 64-bit counter-based noise generator
        self.fn_hz, self.fn_var = output_noise_poles(noise, params.volts_per_ln)
        n = self.gain.size
        self.fn = (np.sqrt(self.fn_var)[:, None] * rng.standard_normal((len(self.fn_hz), n))).astype(np.float64)
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

    def steady_state(self, photocurrent_a: ArrayLike) -> np.ndarray:
        """Noise-free settled output (ln units) for a constant photocurrent (H, W)."""
        i = np.asarray(photocurrent_a, float).reshape(-1)
        return pm.log(i * self.gain + self.dark_a).reshape(self.shape)

    def process(self, photocurrent_a: ArrayLike, t_s: ArrayLike) -> np.ndarray:
        """Advance over T steps and return the output (T, H, W) float32, in ln units.

        Parameters
        ----------
        photocurrent_a : (T, H, W) photocurrent; sample k is held from the end of
            the previous step to ``t_s[k]``.
        t_s : (T,) strictly increasing end times of the steps, after the current time.
        """
        p = self.params
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
        bad = count_invalid(flat, nonnegative=True)
        if not bad and np.any(self.dark_a <= 0):
            dark_free = self.dark_a <= 0
            bad = int(np.count_nonzero(flat[:, dark_free] * self.gain[dark_free] <= 0))
        if bad:
            raise ValueError(f"photocurrent must be finite and >= 0 (> 0 where the dark current is 0): "
                             f"{bad} of {flat.size} values are not")
        out = np.empty(flat.shape, np.float32)
        fc_ref = p.cutoff_hz if math.isfinite(p.cutoff_hz) else (-1.0 if not math.isfinite(p.max_cutoff_hz) else 1e300)
        _kernels.photoreceptor(
            flat, dt, self.gain, self.dark_a, v1, v2, fn, self.fn_hz, self.fn_var, np.uint64(self.key), self.step,
            fc_ref, p.cutoff_ref_photocurrent_a, p.max_cutoff_hz if math.isfinite(p.max_cutoff_hz) else np.inf,
            p.second_pole_hz or 0.0, math.pi * elementary_charge if self.noise.shot_noise else 0.0,
            out,
        )
        self.v1, self.v2, self.fn = v1, v2, fn
        self.t_s = float(t[-1])
        self.step += len(t)
        self.started = True
        return out.reshape((len(t),) + self.shape)
