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

from gevsim._validate import increasing, real, real_array, size
from gevsim.events.types import BRIGHTNESS_DTYPE

HIGH_PASS_CUTOFF_RAD_S = 2.0 * math.pi * 0.1  # assumed: authors' code default, 0.1 Hz
COMPLEMENTARY_CUTOFF_RAD_S = 2.0 * math.pi * 0.5  # assumed: authors' code default, 0.5 Hz
#: Default ON and OFF contrast step of an event (ln units): the usual DVS threshold (assumed).
CONTRAST_LN = 0.2

_INF = np.iinfo(np.int64).max


@njit(cache=True)
def _filter(ex, ey, et, ec, frames, frame_t, out_t, state, last, alpha):
    """Exact event/frame-driven first-order filter; ``state``/``last`` (H, W) are updated in place."""
    n, nf, m = et.shape[0], frame_t.shape[0], out_t.shape[0]
    h, w = state.shape
    out = np.empty((m, h, w))
    ref = frames[0]
    ie, jf = 0, 0
    for k in range(m):
        tout = out_t[k]
        while True:
            te = et[ie] if ie < n else _INF
            tf = frame_t[jf] if jf < nf else _INF
            if te > tout and tf > tout:
                break
            if tf <= te:  # new reference: bring every pixel to tf first
                for y in range(h):
                    for x in range(w):
                        b = math.exp(-alpha * (tf - last[y, x]) * 1e-6)
                        state[y, x] = ref[y, x] + (state[y, x] - ref[y, x]) * b
                        last[y, x] = tf
                ref = frames[jf]
                jf += 1
            else:
                x, y = ex[ie], ey[ie]
                b = math.exp(-alpha * (te - last[y, x]) * 1e-6)
                state[y, x] = ref[y, x] + (state[y, x] - ref[y, x]) * b + ec[ie]
                last[y, x] = te
                ie += 1
        for y in range(h):
            for x in range(w):
                b = math.exp(-alpha * (tout - last[y, x]) * 1e-6)
                out[k, y, x] = ref[y, x] + (state[y, x] - ref[y, x]) * b
    return out


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


def _run(events, frame_t_us, frames, frames_t, width, height, c_on, c_off, alpha, initial):
    width, height = size(width, height)
    out_t = _check_times(frame_t_us, "frame_t_us")
    x, y, t, c = _unpack(events, width, height, c_on, c_off)
    state = np.zeros((height, width)) if initial is None else np.array(initial, dtype=np.float64)
    if state.shape != (height, width):
        raise ValueError(f"initial must have the shape ({height}, {width}) of the sensor, got {state.shape}")
    real_array(state, "initial")
    t0 = min(out_t[0], frames_t[0] if frames_t.size else out_t[0], t[0] if t.size else out_t[0])
    last = np.full((height, width), t0, dtype=np.int64)
    if frames is None:
        frames = np.zeros((1, height, width))
    return _filter(x, y, t, c, frames, frames_t, out_t, state, last, alpha)


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
