"""Registry of reconstruction methods: the one place that names them (full names such as ``dct_rc``).

Each method reads one emulator's event stream from an emulation file and returns
frames at the ground-truth times, before the level is set and the frames are scored
(:func:`gevsim.evaluation.reconstruct_file`). Gradient methods (``dct``, ``sor`` and
their ``_rc`` twins on the resolution-compressed stream) decode the gradient events
from the stored initial ternary state up to each frame and solve the Poisson problem
(Lehtonen et al.); brightness methods (``direct``, ``high_pass``, ``complementary``)
integrate brightness events (Scheerlinck, Barnes & Mahony 2018). Learned methods (``e2v`` on brightness events,
``e2v_gradient`` and ``e2v_gradient_rc`` on gradient events) run the shipped weights of one small recurrent
network (FireNet's architecture) on each event type's encoding (:mod:`gevsim.learn`).

Adding a method is its algorithm in :mod:`gevsim.reconstruct` plus one entry in
:data:`METHODS` (colour-science's ``*_METHODS`` pattern).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from gevsim import _portable as pm
from gevsim.emulation import layout
from gevsim.emulation.emulators import EMULATORS
from gevsim.emulation.frames import file_log_mode, linear_intensity
from gevsim.errors import ConfigError, suggest
from gevsim.evaluation.streams import contrast_steps, decoded_states, frame_windows, stream_of
from gevsim.io import EventReader
from gevsim.reconstruct import brightness
from gevsim.reconstruct.gradient import GradientReconstructor

__all__ = ["METHODS", "Method", "check_method"]

@dataclass(frozen=True)
class Method:
    """One registry entry.

    Attributes
    ----------
    emulator : the emulator (:data:`~gevsim.emulation.emulators.EMULATORS`) whose stream it reads.
    run : ``run(reader, gt, t_us, *, c, contrast_ln, is_log)``: frames (M, H, W) at ``t_us``, in the
        units of the ground truth ``gt`` (ln for scene mode, intensity for frame mode).
    needs_aps : it fuses APS frames (the run must emulate them).
    """

    emulator: str
    run: Callable[..., np.ndarray]
    needs_aps: bool = False

    @property
    def stream(self) -> str:
        return EMULATORS[self.emulator].stream


def _poisson(solver: str, emulator: str, *, rc: bool) -> Callable[..., np.ndarray]:
    """Decode ``emulator``'s gradient events up to each frame and solve with ``solver``."""
    def run(r: EventReader, gt, t_us, *, c, contrast_ln, is_log) -> np.ndarray:
        theta, states = decoded_states(r, emulator, t_us, gt.shape[1:])
        reconstructor = GradientReconstructor(gt.shape[1:], theta, rc=rc, method=solver, c=c)
        frames = np.empty_like(gt)
        for k, state in enumerate(states):
            frames[k] = reconstructor.frame(state)
        return frames
    return run


def _brightness(make: Callable[..., brightness.EventFilter]) -> Callable[..., np.ndarray]:
    """Feed the DVS events, window by window, to the filter ``make(r, t0_us, (h, w), on, off)``
    and take its estimate at each frame time."""
    def run(r: EventReader, gt, t_us, *, c, contrast_ln, is_log) -> np.ndarray:
        on, off = contrast_steps(r, contrast_ln)
        stream = stream_of(r, "dvs")
        t_us = np.asarray(t_us, np.int64)
        first = r.first_t_us(stream)
        t0 = int(t_us[0]) if first is None or first > t_us[-1] else min(int(t_us[0]), first)
        filt = make(r, t0, gt.shape[1:], on, off)
        frames = np.empty(gt.shape)
        for k, windows in enumerate(frame_windows(r, stream, t_us)):
            for a, b in windows:
                filt.feed(r.read(stream, a, b), until_us=b - 1)
            filt.estimate(int(t_us[k]), frames[k])
        return _in_units(r, frames, is_log)
    return run


def _in_units(r: EventReader, frames: np.ndarray, is_log: bool) -> np.ndarray:
    """Frames from the DVS's log domain in the ground truth's units: frame mode compares intensities, so the log
    its DVS saw is undone there."""
    if is_log:
        return frames
    try:
        return linear_intensity(frames, **file_log_mode(r.attrs))
    except (TypeError, ValueError) as exc:  # the file's log_mode attributes are untrusted
        raise ConfigError(f"corrupt root attribute log_mode or linlog_threshold: {exc}", source=str(r.path)) from None


def _learned(name: str) -> Callable[..., np.ndarray]:
    """The shipped network ``name`` (:mod:`gevsim.learn.shipped`) on its encoding of its emulator's events at each
    frame time. Its output is in the units of its input's log domain: undone for DVS events in frame mode (as
    for the filters); gradient events in frame mode live on the frames' own values, as the Poisson methods'."""
    def run(r: EventReader, gt, t_us, *, c, contrast_ln, is_log) -> np.ndarray:
        from gevsim.learn.encode import encode
        from gevsim.learn.shipped import SHIPPED, shipped

        emulator = SHIPPED[name]
        stream_of(r, emulator)  # one line naming the file when the stream is missing
        model = shipped(name)
        frames = model.run(encode(r, emulator, t_us, gt.shape[1:], contrast_ln=contrast_ln))  # trained at c = 3.6
        return _in_units(r, frames, is_log) if emulator == "dvs" else frames
    return run


def _direct(r, t0, shape, on, off):  # events only: starts from a flat image, like the filters
    h, w = shape
    return brightness.EventFilter(width=w, height=h, contrast_on_ln=on, contrast_off_ln=off, t0_us=t0)


def _high_pass(r, t0, shape, on, off):
    h, w = shape
    return brightness.EventFilter(width=w, height=h, contrast_on_ln=on, contrast_off_ln=off,
                                  cutoff_rad_s=brightness.HIGH_PASS_CUTOFF_RAD_S, t0_us=t0)


def _complementary(r, t0, shape, on, off):
    h, w = shape
    if layout.APS not in r.frame_names:
        raise ConfigError("the complementary filter needs APS frames: emulate with aps = true", source=str(r.path))
    aps, aps_t = r.frames(layout.APS)
    offset = r.array_attrs(f"/frames/{layout.APS}").get("offset_dn", 0.0)
    if not len(aps) or aps.ndim != 3 or not isinstance(offset, float | int | np.number) or not np.isfinite(offset):
        raise ConfigError(f"corrupt /frames/{layout.APS}: expected (N >= 1, H, W) frames and a finite offset_dn, "
                          f"got {aps.shape} frames, offset_dn = {offset!r}", source=str(r.path))
    aps_log = pm.log(np.maximum(aps.astype(np.float64) - offset, 1.0))  # DN above black level, in ln
    aps_t = np.asarray(aps_t, np.int64)
    if aps_t.size:
        t0 = min(t0, int(aps_t[0]))
    return brightness.EventFilter(width=w, height=h, contrast_on_ln=on, contrast_off_ln=off,
                                  cutoff_rad_s=brightness.COMPLEMENTARY_CUTOFF_RAD_S, frames_log=aps_log,
                                  frames_t_us=aps_t, initial=aps_log[0], t0_us=t0)


#: Reconstruction methods by their full name.
METHODS: dict[str, Method] = {
    "dct": Method("gradient", _poisson("dct", "gradient", rc=False)),
    "sor": Method("gradient", _poisson("sor", "gradient", rc=False)),
    "dct_rc": Method("gradient_rc", _poisson("dct", "gradient_rc", rc=True)),
    "sor_rc": Method("gradient_rc", _poisson("sor", "gradient_rc", rc=True)),
    "direct": Method("dvs", _brightness(_direct)),
    "high_pass": Method("dvs", _brightness(_high_pass)),
    "complementary": Method("dvs", _brightness(_complementary), needs_aps=True),
    "e2v": Method("dvs", _learned("e2v")),
    "e2v_gradient": Method("gradient", _learned("e2v_gradient")),
    "e2v_gradient_rc": Method("gradient_rc", _learned("e2v_gradient_rc")),
}


def check_method(name: str) -> Method:
    """The registry entry of ``name``; ValueError with a did-you-mean for an unknown one."""
    if not isinstance(name, str) or name not in METHODS:
        raise ValueError(f"unknown reconstruction method {name!r}{suggest(str(name), METHODS)}; "
                         f"choose from {', '.join(METHODS)}")
    return METHODS[name]
