"""Input encodings of the learned reconstruction: one tensor (C, H, W) per ground-truth frame, from the
events of one emulator's stream in the frame's interval (t_us[k-1], t_us[k]] (from t = 0 for k = 0).

Each event type gets its raw encoding plus the parameter-free classical reconstruction from the same
events: the running direct integration for DVS, the exact DCT Poisson solution for gradient events. A
network of ~40 k parameters sees ~10 px around a pixel (its receptive field): it cannot integrate a
gradient field, or a long event history, over the whole frame. Given the classical estimate, it learns
what that estimate gets wrong (noise, flicker, drift) instead. The architecture, loss, data and budget are
the same for every encoding; only the first layer's input width differs.

- ``"dvs"`` (C = 6): a voxel grid of :data:`BINS` temporal bins over the frame interval, each event spread
  bilinearly in time between its two nearest bins (Rebecq, Ranftl, Koltun & Scaramuzza, "High speed and
  high dynamic range video with an event camera", TPAMI 2019, Sec. 3.1), weighted by its contrast step in
  ln units (+contrast_on or -contrast_off, physical units rather than E2VID's per-window normalisation, so
  sensors with other thresholds give comparable inputs); then the running sum of the signed contrast
  steps since t = 0, zero mean per frame.
- ``"gradient"``, ``"gradient_rc"`` (C = 3): the decoded ternary state at t_us[k] times the stored
  thresholds, per axis (ln per pixel; the resolution-compressed pair value copied to both pixels, as
  :func:`gevsim.reconstruct.gradient.quantized_gradients` does), then the DCT Poisson solution of that
  state (zero mean).

Every channel is in the units of the stream: ln photocurrent in scene mode, log gray in frame mode.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gevsim.evaluation.streams import contrast_steps, decoded_states, frame_windows, stream_of
from gevsim.io import EventReader
from gevsim.reconstruct.gradient import GradientReconstructor, quantized_gradients

__all__ = ["BINS", "ENCODINGS", "Encoding", "encode", "voxel_grid"]

#: Temporal bins of the DVS voxel grid (E2VID's B = 5).
BINS = 5


@dataclass(frozen=True)
class Encoding:
    """One registry entry: the emulator whose stream it reads, its channel count and its encoder
    ``run(reader, t_us, shape, *, contrast_ln, c) -> (M, channels, H, W) float32``."""

    emulator: str
    channels: int
    run: Callable[..., np.ndarray]


def voxel_grid(x: np.ndarray, y: np.ndarray, t_us: np.ndarray, weight: np.ndarray, *, t0_us: float, t1_us: float,
               shape: tuple[int, int], bins: int = BINS) -> np.ndarray:
    """(bins, H, W) float64: each event's ``weight`` split between the two bins nearest its normalised time
    t* = (bins - 1)(t - t0)/(t1 - t0), bin b getting weight * max(0, 1 - |b - t*|) (E2VID, Sec. 3.1). An
    empty interval (t1 <= t0) puts every event in the last bin."""
    h, w = shape
    grid = np.zeros(bins * h * w, np.float64)
    if len(x):
        span = float(t1_us) - float(t0_us)
        ts = (np.full(len(x), bins - 1.0) if span <= 0 else
              np.clip((bins - 1) * (np.asarray(t_us, np.float64) - t0_us) / span, 0.0, bins - 1.0))
        lo = np.floor(ts).astype(np.int64)
        frac = ts - lo
        hi = np.minimum(lo + 1, bins - 1)
        pix = np.asarray(y, np.int64) * w + np.asarray(x, np.int64)
        weight = np.asarray(weight, np.float64)
        np.add.at(grid, lo * h * w + pix, weight * (1.0 - frac))
        np.add.at(grid, hi * h * w + pix, weight * frac)
    return grid.reshape(bins, h, w)


def _dvs(r: EventReader, t_us, shape, *, contrast_ln, c) -> np.ndarray:
    on, off = contrast_steps(r, contrast_ln)
    stream = stream_of(r, "dvs")
    h, w = shape
    out = np.empty((len(t_us), BINS + 1, h, w), np.float32)
    total = np.zeros(h * w, np.float64)  # running direct integration since t = 0
    for k, windows in enumerate(frame_windows(r, stream, t_us)):
        t0 = float(t_us[k - 1]) if k else min(0.0, float(t_us[0]))
        grid = np.zeros((BINS, h, w), np.float64)
        for a, b in windows:
            ev = r.read(stream, a, b)
            step = np.where(ev["p"], on, -off)
            grid += voxel_grid(ev["x"], ev["y"], ev["t"], step, t0_us=t0, t1_us=float(t_us[k]), shape=(h, w))
            np.add.at(total, ev["y"].astype(np.int64) * w + ev["x"], step)
        out[k, :BINS] = grid
        out[k, BINS] = (total - total.mean()).reshape(h, w)
    return out


def _gradient(emulator: str, *, rc: bool) -> Callable[..., np.ndarray]:
    def run(r: EventReader, t_us, shape, *, contrast_ln, c) -> np.ndarray:
        theta, states = decoded_states(r, emulator, t_us, tuple(shape))
        solver = GradientReconstructor(tuple(shape), theta, rc=rc, method="dct", c=c)
        out = np.empty((len(t_us), 3) + tuple(shape), np.float32)
        for k, state in enumerate(states):
            out[k, 0], out[k, 1] = quantized_gradients(state, theta, rc=rc)
            poisson = solver.frame(state)
            out[k, 2] = poisson - poisson.mean()
        return out
    return run


#: Input encodings by the emulator they read (``gevsim train --events``).
ENCODINGS: dict[str, Encoding] = {
    "dvs": Encoding("dvs", BINS + 1, _dvs),
    "gradient": Encoding("gradient", 3, _gradient("gradient", rc=False)),
    "gradient_rc": Encoding("gradient_rc", 3, _gradient("gradient_rc", rc=True)),
}


def encode(reader: EventReader, emulator: str, t_us: np.ndarray | list[int], shape: tuple[int, int], *,
           contrast_ln: float | None = None, c: float = 3.6) -> np.ndarray:
    """The network inputs (M, C, H, W) float32 of ``emulator``'s stream at the M frame times ``t_us``
    (a key of :data:`ENCODINGS`; ValueError otherwise). ``contrast_ln``: the DVS contrast step (default:
    the file's DVS thresholds); ``c``: the Poisson scale of the gradient encodings' DCT channel."""
    if emulator not in ENCODINGS:
        raise ValueError(f"unknown encoding {emulator!r}; choose from {', '.join(ENCODINGS)}")
    t_us = np.asarray(t_us, np.int64)
    return ENCODINGS[emulator].run(reader, t_us, tuple(int(n) for n in shape), contrast_ln=contrast_ln, c=c)
