"""Non-learned log-intensity reconstruction from brightness (DVS) events.

Three per-pixel filters share one exact integrator (:func:`_filter`). Between
updates a pixel's estimate L relaxes towards a reference R with rate alpha,

    dL/dt = sum_i c_i delta(t - t_i) - alpha (L - R),

so over dt it becomes ``R + (L - R) exp(-alpha dt)`` and an event adds its
contrast c_i (+c_on for ON, -c_off for OFF). Nothing is discretised in time.

- :func:`direct_integration`: alpha = 0, R = 0 (the per-pixel step sum).
- :func:`high_pass_filter`: R = 0, alpha > 0 (Scheerlinck, Barnes & Mahony,
  "Continuous-time intensity estimation using event cameras", ACCV 2018,
  events-only filter).
- :func:`complementary_filter`: R = log of the latest APS frame (same paper).

Events carry no absolute level: the estimates are relative to ``initial``
(default 0, for the complementary filter the first APS frame); callers
zero-centre them or match their mean to a reference before scoring.
An estimate at time t includes every event with timestamp <= t.

Cutoff defaults come from the authors' ROS code (github.com/cedric-scheerlinck/
dvs_image_reconstruction), whose dynamic-reconfigure ``Cutoff_frequency`` is
given in Hz and multiplied by 2 pi: 0.1 Hz for the events-only high-pass
filter (``pure_event_reconstruction.cfg``; an earlier revision used 0.06 Hz)
and 0.5 Hz for the complementary filter (``complementary_filter.cfg``; an
earlier revision used 0.2 Hz). The paper's own text could not be consulted
here, so these values are assumed defaults. The code's extra per-event decay
(``Cutoff_frequency_per_event_component``) is not part of the paper's filter
and is not modelled.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from gevsim._portable import exp_scalar
from gevsim._validate import increasing, real, real_array, size
from gevsim.events.types import BRIGHTNESS_DTYPE

HIGH_PASS_CUTOFF_RAD_S = 2.0 * math.pi * 0.1  # assumed: authors' code default, 0.1 Hz
COMPLEMENTARY_CUTOFF_RAD_S = 2.0 * math.pi * 0.5  # assumed: authors' code default, 0.5 Hz
#: Default ON and OFF contrast step of an event (ln units): the usual DVS threshold (assumed).
CONTRAST_LN = 0.2

_INF = np.iinfo(np.int64).max


@njit(cache=True)
def _advance(ex, ey, et, ec, frames, frame_t, jf, until, state, last, alpha):
    """Apply the events (all with t <= ``until``) and the reference frames with t <= ``until``
    in time order (a frame before an event at the same time); ``state``/``last`` (H, W) are
    updated in place. ``jf`` frames were applied before; returns the new count."""
    n, nf = et.shape[0], frame_t.shape[0]
    h, w = state.shape
    ref = frames[jf - 1] if jf > 0 else frames[0]
    ie = 0
    while True:
        te = et[ie] if ie < n else _INF
        tf = frame_t[jf] if jf < nf else _INF
        if te > until and tf > until:
            break
        if tf <= te:  # new reference: bring every pixel to tf first
            for y in range(h):
                for x in range(w):
                    b = exp_scalar(-alpha * (tf - last[y, x]) * 1e-6)
                    state[y, x] = ref[y, x] + (state[y, x] - ref[y, x]) * b
                    last[y, x] = tf
            ref = frames[jf]
            jf += 1
        else:
            x, y = ex[ie], ey[ie]
            b = exp_scalar(-alpha * (te - last[y, x]) * 1e-6)
            state[y, x] = ref[y, x] + (state[y, x] - ref[y, x]) * b + ec[ie]
            last[y, x] = te
            ie += 1
    return jf


@njit(cache=True)
def _estimate(frames, jf, tout, state, last, alpha, out):
    """The estimate at ``tout`` (every event and frame up to it applied) into ``out`` (H, W)."""
    h, w = state.shape
    ref = frames[jf - 1] if jf > 0 else frames[0]
    for y in range(h):
        for x in range(w):
            b = exp_scalar(-alpha * (tout - last[y, x]) * 1e-6)
            out[y, x] = ref[y, x] + (state[y, x] - ref[y, x]) * b


def _check_times(t, name):
    t = increasing(t, name, unit="us")
    if t.dtype.kind == "f" and np.any(t != np.round(t)):
        raise ValueError(f"{name} must hold integer microseconds")
    return t.astype(np.int64)


def _contrasts(c_on, c_off):
    return (real(c_on, "contrast_on_ln", low=0.0, low_open=True),
            real(c_off, "contrast_off_ln", low=0.0, low_open=True))


def _unpack(events, width, height, c_on, c_off):
    if not isinstance(events, np.ndarray) or events.dtype != BRIGHTNESS_DTYPE:
        got = getattr(events, "dtype", type(events).__name__)
        raise TypeError(f"events must be a structured array of BRIGHTNESS_DTYPE, got {got}")
    t = events["t"].astype(np.int64)
    if t.size > 1 and np.any(np.diff(t) < 0):
        raise ValueError("events must be sorted by timestamp (non-decreasing t)")
    x, y = events["x"].astype(np.int64), events["y"].astype(np.int64)
    bad = (x < 0) | (x >= width) | (y < 0) | (y >= height)
    if np.any(bad):
        i = int(np.argmax(bad))
        raise ValueError(f"event {i} at (x={x[i]}, y={y[i]}) lies outside the {width}x{height} sensor")
    c = np.where(events["p"], c_on, -c_off).astype(np.float64)
    return x, y, t, c


class EventFilter:
    """The exact filter of this module, fed events window by window (bounded memory).

    Feed every event in time order with :meth:`feed` (each window's events up to a time
    ``until_us``, the next window's after it), and read the estimate at any time up to the
    last ``until_us`` with :meth:`estimate`. Cutting the events into windows does not change
    the result, bit for bit.

    Parameters
    ----------
    width, height : sensor size in pixels.
    contrast_on_ln, contrast_off_ln : contrast step of an ON / OFF event (ln units).
    cutoff_rad_s : relaxation rate alpha (rad/s); 0 integrates.
    frames_log, frames_t_us : references (K, H, W) in ln units from their times (K,) in us
        (default: none, R = 0).
    initial : (H, W) state at ``t0_us`` (default zeros).
    t0_us : time (us) of ``initial``: no later than the first event, frame or estimate.
    """

    def __init__(self, *, width: int, height: int, contrast_on_ln: float = CONTRAST_LN,
                 contrast_off_ln: float = CONTRAST_LN, cutoff_rad_s: float = 0.0, frames_log: ArrayLike | None = None,
                 frames_t_us: ArrayLike | None = None, initial: ArrayLike | None = None, t0_us: int):
        self.width, self.height = size(width, height)
        self.c_on, self.c_off = _contrasts(contrast_on_ln, contrast_off_ln)
        self.alpha = real(cutoff_rad_s, "cutoff_rad_s", low=0.0)
        shape = (self.height, self.width)
        if frames_log is None:
            self.frames, self.frames_t = np.zeros((1, *shape)), np.zeros(0, dtype=np.int64)
        else:
            self.frames_t = _check_times(frames_t_us, "frames_t_us")
            self.frames = np.ascontiguousarray(frames_log, dtype=np.float64)
            if self.frames.shape != (self.frames_t.size, *shape):
                raise ValueError(f"frames_log must have shape ({self.frames_t.size}, {self.height}, {self.width}) "
                                 f"to match frames_t_us, got {self.frames.shape}")
            real_array(self.frames, "frames_log")
        self.state = np.zeros(shape) if initial is None else np.array(initial, dtype=np.float64)
        if self.state.shape != shape:
            raise ValueError(f"initial must have the shape {shape} of the sensor, got {self.state.shape}")
        real_array(self.state, "initial")
        self.last = np.full(shape, int(t0_us), dtype=np.int64)
        self.applied_frames = 0
        self.until_us: int | None = None

    def feed(self, events: np.ndarray, *, until_us: int) -> None:
        """Apply ``events`` (BRIGHTNESS_DTYPE, sorted, all with ``t <= until_us`` and after the
        previous window's ``until_us``) and the reference frames up to ``until_us``."""
        x, y, t, c = _unpack(events, self.width, self.height, self.c_on, self.c_off)
        self._feed(x, y, t, c, until_us)

    def _feed(self, x, y, t, c, until_us) -> None:
        until_us = int(until_us)
        if self.until_us is not None and until_us < self.until_us:
            raise ValueError(f"until_us={until_us} us goes back before the previous window's {self.until_us} us")
        if t.size and (t[-1] > until_us or (self.until_us is not None and t[0] <= self.until_us)):
            raise ValueError(f"events from t={int(t[0])} to {int(t[-1])} us fall outside the window "
                             f"({self.until_us}, {until_us}] us")
        self.applied_frames = _advance(x, y, t, c, self.frames, self.frames_t, self.applied_frames, until_us,
                                       self.state, self.last, self.alpha)
        self.until_us = until_us

    def estimate(self, t_us: int, out: np.ndarray | None = None) -> np.ndarray:
        """The (H, W) log estimate at ``t_us`` (from the events fed; ``t_us`` no later than the
        last window's ``until_us``, and no event after ``t_us`` fed yet)."""
        if out is None:
            out = np.empty((self.height, self.width))
        _estimate(self.frames, self.applied_frames, int(t_us), self.state, self.last, self.alpha, out)
        return out


def _run(events, frame_t_us, frames, frames_t, width, height, c_on, c_off, alpha, initial):
    width, height = size(width, height)
    out_t = _check_times(frame_t_us, "frame_t_us")
    x, y, t, c = _unpack(events, width, height, c_on, c_off)
    t0 = min(out_t[0], frames_t[0] if frames_t.size else out_t[0], t[0] if t.size else out_t[0])
    filt = EventFilter(width=width, height=height, contrast_on_ln=c_on, contrast_off_ln=c_off, cutoff_rad_s=alpha,
                       frames_log=frames, frames_t_us=frames_t if frames is not None else None, initial=initial,
                       t0_us=t0)
    out = np.empty((out_t.size, height, width))
    ends = np.searchsorted(t, out_t, side="right")  # events with t <= out_t[k]
    a = 0
    for k, tout in enumerate(out_t):
        b = int(ends[k])
        filt._feed(x[a:b], y[a:b], t[a:b], c[a:b], tout)
        filt.estimate(tout, out[k])
        a = b
    return out


def direct_integration(events: np.ndarray, frame_t_us: ArrayLike, *, width: int, height: int,
                       contrast_on_ln: float = CONTRAST_LN, contrast_off_ln: float = CONTRAST_LN,
                       initial: ArrayLike | None = None) -> np.ndarray:
    """Per-pixel sum of contrast steps up to each of ``frame_t_us``: (M, H, W) float64 log frames.

    An ON event adds ``contrast_on_ln``, an OFF event subtracts ``contrast_off_ln`` (ln units).
    ``initial`` (H, W) is the log image before the first event (default zeros).
    """
    c_on, c_off = _contrasts(contrast_on_ln, contrast_off_ln)
    empty_t = np.zeros(0, dtype=np.int64)
    return _run(events, frame_t_us, None, empty_t, width, height, c_on, c_off, 0.0, initial)


def high_pass_filter(
    events: np.ndarray, frame_t_us: ArrayLike, *, width: int, height: int, contrast_on_ln: float = CONTRAST_LN,
    contrast_off_ln: float = CONTRAST_LN, cutoff_rad_s: float = HIGH_PASS_CUTOFF_RAD_S,
    initial: ArrayLike | None = None
) -> np.ndarray:
    """Events-only high-pass filter of Scheerlinck et al. (ACCV 2018): (M, H, W) float64 log frames.

    Each pixel decays as exp(-cutoff_rad_s dt) between its events and jumps by
    the event contrast (``contrast_on_ln`` / ``-contrast_off_ln``, ln units).
    ``initial`` (default zeros) is the state at the earliest event or output time.
    """
    c_on, c_off = _contrasts(contrast_on_ln, contrast_off_ln)
    alpha = real(cutoff_rad_s, "cutoff_rad_s", low=0.0)
    empty_t = np.zeros(0, dtype=np.int64)
    return _run(events, frame_t_us, None, empty_t, width, height, c_on, c_off, alpha, initial)


def complementary_filter(
    events: np.ndarray,
    frames_log: ArrayLike,
    frames_t_us: ArrayLike,
    frame_t_us_out: ArrayLike,
    *,
    width: int,
    height: int,
    contrast_on_ln: float = CONTRAST_LN,
    contrast_off_ln: float = CONTRAST_LN,
    cutoff_rad_s: float = COMPLEMENTARY_CUTOFF_RAD_S,
    initial: ArrayLike | None = None,
) -> np.ndarray:
    """Complementary filter of Scheerlinck et al. (ACCV 2018) fusing events with APS frames.

    dL/dt = events - cutoff_rad_s (L - L_F), with L_F = ``frames_log[k]`` from
    ``frames_t_us[k]`` until the next frame (``frames_log[0]`` before the first
    one). Events step by ``contrast_on_ln`` / ``-contrast_off_ln`` (ln units).
    ``initial`` is the state at the earliest timestamp given (default
    ``frames_log[0]``). Returns (M, H, W) float64 log frames at ``frame_t_us_out``.
    """
    c_on, c_off = _contrasts(contrast_on_ln, contrast_off_ln)
    alpha = real(cutoff_rad_s, "cutoff_rad_s", low=0.0)
    width, height = size(width, height)
    frames = np.asarray(frames_log, dtype=np.float64)
    frames_t = _check_times(frames_t_us, "frames_t_us")
    if frames.ndim != 3 or frames.shape[1:] != (height, width) or frames.shape[0] != frames_t.size:
        raise ValueError(
            f"frames_log must have shape ({frames_t.size}, {height}, {width}) to match frames_t_us, got {frames.shape}"
        )
    real_array(frames, "frames_log")
    frames = np.ascontiguousarray(frames)
    if initial is None:
        initial = frames[0]
    return _run(events, frame_t_us_out, frames, frames_t, width, height, c_on, c_off, alpha, initial)


METHODS = {"direct": direct_integration, "high_pass": high_pass_filter}
"""Events-only reconstructions by name (the complementary filter also needs frames)."""
