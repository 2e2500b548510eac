"""Reading what a reconstruction method needs from an emulation file, checked (a file is untrusted): a stream's
read windows per frame, its stored thresholds and initial ternary state, the decoded ternary state at each
frame time, the DVS contrast steps. Shared by the
methods' registry (:mod:`gevsim.evaluation.methods`) and the learned methods' input encodings (:mod:`gevsim.learn`)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from gevsim.emulation import layout
from gevsim.emulation.emulators import EMULATORS
from gevsim.errors import ConfigError
from gevsim.events import decode
from gevsim.events.gradient import check_ternary_state
from gevsim.io import EventReader
from gevsim.reconstruct import brightness

__all__ = ["contrast_steps", "decoded_states", "decoding_inputs", "frame_windows", "stream_of", "thresholds"]


def stream_of(r: EventReader, emulator: str) -> str:
    stream = EMULATORS[emulator].stream
    if stream not in r.streams:
        raise ConfigError(f"holds no {stream} stream (emulate with {emulator!r} among the emulators)",
                          source=str(r.path))
    return stream


def frame_windows(r: EventReader, stream: str, t_us: np.ndarray | list[int]) -> list[list[tuple[int, int]]]:
    """Per frame k the read windows covering the events in (t_us[k-1], t_us[k]] (from t = 0 for
    k = 0), each of at most :data:`~gevsim.io.event_reader.WINDOW_EVENTS` events: methods read the
    stream window by window, so memory is bounded whatever the duration."""
    out, start = [], 0
    for t in t_us:
        out.append(r.windows(stream, start, int(t) + 1))
        start = max(start, int(t) + 1)
    return out


def thresholds(r: EventReader, emulator: str, shape: tuple[int, ...]) -> np.ndarray:
    """An emulator's stored thresholds: ``shape`` finite numbers > 0 (a file is untrusted), as float64."""
    key = layout.thresholds_key(emulator)
    theta = r.array(key)
    if theta.shape != shape or theta.dtype.kind not in "iuf":
        raise ConfigError(f"corrupt {key}: expected {shape} thresholds, got shape {theta.shape} of {theta.dtype}",
                          source=str(r.path))
    bad = ~(np.isfinite(theta) & (theta > 0))
    if np.any(bad):
        raise ConfigError(f"corrupt {key}: thresholds must be finite and > 0, got {float(theta[bad][0])} "
                          f"({np.count_nonzero(bad)} of {theta.size})", source=str(r.path))
    return theta.astype(np.float64)


def decoding_inputs(r: EventReader, emulator: str, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The stored thresholds and initial ternary state of a gradient stream, checked (a file is untrusted:
    the decoder indexes its tables with these values): ConfigError naming the file otherwise."""
    theta = thresholds(r, emulator, (2,) + tuple(shape))
    try:
        state = check_ternary_state(r.array(layout.initial_state_key(emulator)), shape=(shape[0], shape[1]))
    except ValueError as exc:
        raise ConfigError(f"corrupt {layout.initial_state_key(emulator)}: {exc}", source=str(r.path)) from None
    return theta, state


def decoded_states(r: EventReader, emulator: str, t_us: np.ndarray | list[int],
                   shape: tuple[int, ...]) -> tuple[np.ndarray, Iterator[np.ndarray]]:
    """``emulator``'s stored thresholds and an iterator over its ternary state decoded from the stored initial
    state up to each frame time ``t_us[k]``, reading the stream window by window (memory bounded)."""
    stream = stream_of(r, emulator)
    theta, state = decoding_inputs(r, emulator, shape)

    def states(state: np.ndarray) -> Iterator[np.ndarray]:
        for windows in frame_windows(r, stream, t_us):
            for a, b in windows:
                state = decode(r.read(stream, a, b), state)
            yield state
    return theta, states(state)


def contrast_steps(r: EventReader, contrast_ln: float | None) -> tuple[float, float]:
    """ON/OFF contrast steps: given, else the DVS thresholds stored in the file, else the default."""
    if contrast_ln is not None:
        return float(contrast_ln), float(contrast_ln)
    if layout.thresholds_key("dvs") not in r:
        return brightness.CONTRAST_LN, brightness.CONTRAST_LN  # frame mode stores no DVS thresholds
    on, off = (float(v) for v in thresholds(r, "dvs", (2,)))
    return on, off
