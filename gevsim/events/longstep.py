"""Long steps where nothing happens: a prototype of the DVS path stepped per pixel (issue 37, item 1).

A pixel far from both of its thresholds, with a slow signal, leaps many base steps in one exact
transition of its photoreceptor; near a threshold it takes the reference's base step. A leap is taken
only where the probability that the short-step reference would have seen a threshold crossing inside
it is below ``eps`` (a union bound over the base grid with the exact transition's Gaussian law), so
the two paths' event streams differ by at most ``eps`` per leap (docs/long-steps.md, scheme A).

Covers one pixel model: the photoreceptor pole with shot and amplifier noise, read noise through its
own pole, the output pole (davis346), driving the DVS with its refractory period, reset noise, leak,
threshold mismatch and output offsets. Not wired into the driver.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
from numpy.typing import ArrayLike

from gevsim import _portable as pm
from gevsim._finite import count_invalid
from gevsim.events import _longstep as kern
from gevsim.events.brightness import BrightnessEmulator
from gevsim.events.types import BRIGHTNESS_DTYPE, empty
from gevsim.pixel import Photoreceptor
from gevsim.pixel._cascade import read_coefficients, separated_hz
from gevsim.timebase import check_chunk

__all__ = ["LongStepBrightness"]

#: The default bound on the probability of a missed grid crossing per leap.
EPS = 1e-6
#: Pixels per work item (fixed: the events do not depend on the threads).
BLOCK = 1024


def candidates(n_sub: int, k_max: int) -> tuple[np.ndarray, int]:
    """Leap lengths in base steps: 2^k and 3 2^k below ``n_sub`` (a leap at most 1.5x shorter than the
    bound allows), then n_sub 2^k for k = 0 .. k_max; and how many of the first kind there are."""
    within = sorted({m << k for k in range(n_sub.bit_length()) for m in (1, 3) if (m << k) < n_sub})
    return np.array(within + [n_sub << k for k in range(k_max + 1)], np.int64), len(within)


def _global_table(cand: np.ndarray, h0: float, beta: float, read: tuple[float, float] | None) -> np.ndarray:
    """Per candidate: the output pole's decay (b2, 1 - b2) and the read noise's transition and output
    variance (zeros without read noise)."""
    glob = np.zeros((len(cand), kern.NGLOB))
    for c, n in enumerate(cand):
        d = float(n) * h0
        eb2 = -pm.expm1_scalar(-beta * d)  # as the photoreceptor kernel
        glob[c, 0], glob[c, 1] = 1.0 - eb2, eb2
        if read is not None:
            a_r, c_det, s1, r, s2, cc = read_coefficients(read[0], read[1], beta, d)
            share = cc * (s1 - r)
            glob[c, 2:8] = a_r, c_det, s1, share, cc * s2, share * share
    return glob


class LongStepBrightness:
    """The DVS events of a started photoreceptor and DVS pair, stepped by event-free leaps.

    Parameters
    ----------
    pr, dvs : a :class:`~gevsim.pixel.Photoreceptor` and :class:`~gevsim.events.BrightnessEmulator` that have
        both run to the same time (e.g. :func:`gevsim.validation.measure.start_running`); their fixed patterns,
        thresholds, leak rates, keys and states are copied, and they are left as they are.
    frame_s : the length of every frame given to :meth:`process` (the light is held per frame).
    n_sub : base steps per frame (the driver's sub-steps: the reference's step is frame_s / n_sub).
    eps : bound on the probability that a leap hides a grid crossing of the reference.
    max_frames_log2 : K, the longest leap is 2^K frames (chunks of whole 2^K frames give the same events
        as one call).
    seed : keys the leaps' noise (a different realisation from the reference's; the same law).
    """

    dtype = BRIGHTNESS_DTYPE

    def __init__(self, pr: Photoreceptor, dvs: BrightnessEmulator, *, frame_s: float, n_sub: int,
                 eps: float = EPS, max_frames_log2: int = 6, seed: int = 0):
        from scipy.special import ndtri

        p = pr.params
        if p.second_pole_hz is None:
            raise ValueError("the long-step prototype needs an output pole (second_pole_hz)")
        if len(pr.fn_hz) > pr.n_read:
            raise ValueError("the long-step prototype has no 1/f noise poles (flicker_noise_v must be 0)")
        if not pr.started or (dvs.clock.t_s is not None and abs(dvs.clock.t_s - pr.t_s) > 1e-12):
            raise ValueError("settle the photoreceptor (and run the DVS, if at all, to the same time) before the "
                             "long steps")
        if not (frame_s > 0 and int(n_sub) >= 1 and 0 < eps < 1 and 0 <= int(max_frames_log2) <= 16):
            raise ValueError(f"need frame_s > 0, n_sub >= 1, 0 < eps < 1, 0 <= max_frames_log2 <= 16; got "
                             f"{frame_s!r}, {n_sub!r}, {eps!r}, {max_frames_log2!r}")
        self.shape, self.frame_s, self.n_sub, self.k_max = pr.shape, float(frame_s), int(n_sub), int(max_frames_log2)
        self.cand, self.n_pow = candidates(self.n_sub, self.k_max)
        self.z = -ndtri(eps / (2.0 * self.cand))
        beta = 2.0 * math.pi * p.second_pole_hz
        read = None
        self.g_r = 0.0
        if pr.n_read:
            alpha_r = 2.0 * math.pi * float(separated_hz(pr.fn_hz[0], p.second_pole_hz))
            read = (float(pr.fn_var[0]), alpha_r)
            self.g_r = pm.exp_scalar(alpha_r / (beta - alpha_r) * pm.log_scalar(alpha_r / beta))  # max of G_r
        h0 = self.frame_s / self.n_sub
        self.glob = _global_table(self.cand, h0, beta, read)
        fc_ref, i_ref, fc_max, _ = pr._bandwidth()
        filt = 1.0 if fc_ref > 0 else 0.0
        prs = np.array([fc_ref / i_ref if filt else 0.0, fc_max if filt else 0.0, filt, beta, float(pr.shot_q),
                        float(pr.amp_ln2_hz), h0])
        self.tables = (self.cand, self.z, self.glob, self.n_pow, self.k_max, self.g_r, prs)
        self.gain, self.dark_a = pr.gain, pr.dark_a
        n = pr.gain.size
        offset = (pr.offset_ln if pr.offset_ln is not None else np.zeros(n)).astype(np.float32)
        self.pixel_arrays = (self.gain, self.dark_a, offset, dvs.threshold_on_ln, dvs.threshold_off_ln)
        self.dvs_arrays = (dvs.leak_ln_per_s, dvs.leak_light, dvs._px_x, dvs._px_y)
        self.dvs_scalars = (float(dvs.params.refractory_s), float(dvs.params.reset_noise_ln), np.uint64(dvs.reset_key))
        ref, v_prev = dvs.ref.copy(), dvs.v_prev.copy()
        if dvs.clock.t_s is None:  # the DVS's first sample is the photoreceptor's output now (as its process)
            v_prev = (pr.v2.astype(np.float32) + offset).astype(np.float64)
            ref = dvs.start_ref.copy() if dvs.start_ref is not None else v_prev - dvs.leak_phase * dvs.threshold_on_ln
        read_state = pr.fn[0] if pr.n_read else np.zeros(n)
        #: Per pixel: v1, v2, read state (the photoreceptor's), level, last sample, last event, events (the
        #: DVS's), advances taken (keys the noise).
        self.state: tuple[np.ndarray, ...] = (pr.v1.copy(), pr.v2.copy(), read_state.copy(), ref, v_prev,
                                              dvs.last_t.copy(), dvs.count.copy(), np.zeros(n, np.int64))
        self.key = np.uint64(np.random.default_rng(seed).integers(0, 2**63, dtype=np.int64))
        self.t_s = float(pr.t_s)
        self.frames = 0
        self.cap = 256
        #: Per pixel: advances, leaps under the bound, base steps, leaps while held (see ``_longstep``).
        self.stats = np.zeros((n, 4), np.int64)

    def process(self, photocurrent_a: ArrayLike, t_s: ArrayLike) -> np.ndarray:
        """Events (sorted by time) of F frames of photocurrent (F, H, W), frame k held over
        (t_s[k - 1], t_s[k]]; every frame must last ``frame_s``."""
        current, t, prev = check_chunk(photocurrent_a, t_s, shape=self.shape, name="photocurrent", after=self.t_s)
        if len(t) == 0:
            return empty(self.dtype)
        if not np.allclose(t - prev, self.frame_s, rtol=1e-9, atol=0.0):
            raise ValueError(f"every frame must last frame_s = {self.frame_s!r} s")
        if count_invalid(current, nonnegative=True):
            raise ValueError("photocurrent must be finite and >= 0")
        light = np.ascontiguousarray(current.reshape(len(t), -1), dtype=np.float64)
        while True:
            cap = self.cap
            fill, state, stats, bufs = self._attempt(light, (prev, t, self.n_sub, self.frames), cap)
            if np.all(fill >= 0):
                break
            self.cap *= 2
        self.state, self.stats = state, stats
        self.t_s, self.frames = float(t[-1]), self.frames + len(t)
        self.cap = max(256, int(1.5 * fill.max()) + 16)
        nb = len(fill)
        take = np.concatenate([np.arange(b * cap, b * cap + fill[b]) for b in range(nb)])
        events = np.empty(len(take), self.dtype)
        for name, buf in zip(("t", "x", "y", "p"), bufs):
            events[name] = buf[take]
        return events[np.argsort(events["t"], kind="stable")]

    def _attempt(self, light: np.ndarray, frame: tuple, cap: int) -> tuple[np.ndarray, tuple, np.ndarray, tuple]:
        """One run of the chunk from copies of the state, blocks of :data:`BLOCK` pixels on numba's thread
        count, each with room for ``cap`` events: (events per block (-1: out of room), state, stats, buffers)."""
        nb = (light.shape[1] + BLOCK - 1) // BLOCK
        state = tuple(a.copy() for a in self.state)
        stats = self.stats.copy()
        bufs = (np.empty(nb * cap, np.int64), np.empty(nb * cap, np.int16), np.empty(nb * cap, np.int16),
                np.empty(nb * cap, np.bool_))

        def block(b: int) -> int:
            n = kern.run_pixels(b * BLOCK, min(light.shape[1], (b + 1) * BLOCK), light, frame, self.pixel_arrays,
                                self.tables, self.dvs_arrays, self.dvs_scalars, state, self.key, bufs, b * cap,
                                (b + 1) * cap, stats)
            return n - b * cap if n >= 0 else -1

        workers = min(nb, numba.get_num_threads())
        if workers > 1:
            with ThreadPoolExecutor(workers) as pool:
                return np.array(list(pool.map(block, range(nb))), np.int64), state, stats, bufs
        return np.array([block(b) for b in range(nb)], np.int64), state, stats, bufs
