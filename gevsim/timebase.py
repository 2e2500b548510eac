"""Time: the grid an emulation steps on (:class:`TimeGrid`), and the checks shared by every
stage that consumes a chunk of samples over time (:func:`check_chunk`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from gevsim._validate import FieldError, integer, real, real_array
from gevsim.config import FromTable

#: The shortest duration an emulation may have: event files count time in whole microseconds, so a
#: shorter one has no tick to put an event on and no length to give a rate.
MIN_DURATION_S = 1e-6
#: The longest recording an event file holds: one day (its ``t_end_us`` is checked against this when it is
#: read, :mod:`gevsim.io.checks`), so emulations and frame sequences are refused beyond it before they run.
MAX_DURATION_S = 86_400.0
#: The highest ground-truth frame rate: frame times are whole microseconds, so faster frames would share one.
MAX_FRAME_RATE_HZ = 1e6
#: The most ground-truth frames one emulation writes (each is two float32 images in the file).
MAX_FRAMES = 1_000_000


@dataclass(frozen=True)
class TimeGrid(FromTable):
    """The time grid of an emulation, the one place its defaults are defined.

    Emulation, dataset and study configs read these keys from their main table
    (:meth:`~gevsim.config.FromTable.from_section`).

    Parameters
    ----------
    duration_s : how long to emulate; None: the scene's ``[sequence] duration_s``.
    step_s : the pixel model's time step (a whole number of them must fill the duration).
    chunk_steps : steps processed per chunk (bounds memory, not results); None: sized to the memory budget
        (:func:`gevsim.resources.budget_chunk_steps`).
    frame_rate_hz : ground-truth frames per second (0: none; at most :data:`MAX_FRAMES` frames).
    """

    duration_s: float | None = None
    step_s: float = 2e-5  # issue 22: noise and flicker rates within 6 % of 5 us (benchmarks/step_convergence.py)
    chunk_steps: int | None = None  # issue 37: from the memory budget (at most 256), unless given
    frame_rate_hz: float = 1000.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "step_s", real(self.step_s, "step_s", low=0.0, low_open=True))
        if self.chunk_steps is not None:
            object.__setattr__(self, "chunk_steps", integer(self.chunk_steps, "chunk_steps", low=1))
        object.__setattr__(self, "frame_rate_hz", real(self.frame_rate_hz, "frame_rate_hz", low=0.0,
                                                       high=MAX_FRAME_RATE_HZ))
        if self.duration_s is not None:  # after frame_rate_hz is known finite: the frame count needs it
            object.__setattr__(self, "duration_s", real(self.duration_s, "duration_s", low=0.0, low_open=True))
            _check_duration(self.duration_s)
            self._check_frames(self.duration_s)
        if self.duration_s is not None and self.step_s >= self.duration_s:
            raise FieldError("step_s", f"step_s = {self.step_s} must be shorter than duration_s = {self.duration_s}")

    def steps(self, duration_s: float) -> int:
        """The number of steps in ``duration_s`` (the grid's own duration, or the scene's when it has none);
        FieldError when it is not a whole number of steps longer than one."""
        _check_duration(duration_s)
        self._check_frames(duration_s)
        if self.step_s >= duration_s:
            raise FieldError("step_s", f"step_s = {self.step_s} must be shorter than the duration {duration_s} s")
        steps = duration_s / self.step_s
        if abs(steps - round(steps)) > 1e-6 * steps:
            raise FieldError("step_s", f"the duration {duration_s} s is not a whole number of steps of "
                                       f"{self.step_s} s")
        return int(round(steps))

    def _check_frames(self, duration_s: float) -> None:
        frames: float = 0
        if self.frame_rate_hz > 0:
            product = duration_s * self.frame_rate_hz  # inf when both are huge: more than any limit
            frames = math.floor(product + 1e-9) + 1 if math.isfinite(product) else math.inf
        if frames > MAX_FRAMES:
            raise FieldError("frame_rate_hz", f"frame_rate_hz = {self.frame_rate_hz:g} over {duration_s:g} s makes "
                                              f"{frames:.4g} ground-truth frames; at most {MAX_FRAMES} are written "
                                              "(1000 s at 1 kHz): lower frame_rate_hz")

    def frame_times_s(self, duration_s: float) -> np.ndarray:
        """Ground-truth frame times in [0, ``duration_s``] (none when ``frame_rate_hz`` is 0)."""
        if self.frame_rate_hz <= 0:
            return np.zeros(0)
        return np.arange(0.0, duration_s + 1e-12, 1.0 / self.frame_rate_hz)


def _check_duration(duration_s: float) -> None:
    if duration_s < MIN_DURATION_S:
        raise FieldError("duration_s", f"duration_s = {duration_s:g} is shorter than 1 us, the clock tick of event "
                                       "files (timestamps are whole microseconds)")
    if duration_s > MAX_DURATION_S:
        raise FieldError("duration_s", f"duration_s = {duration_s:g} is longer than {MAX_DURATION_S:g} s (a day), "
                                       "the longest recording an event file holds")


def check_chunk(values: ArrayLike, t_s: ArrayLike, *, shape: Sequence[int], name: str,
                after: float | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validate a chunk of samples ``values`` (T, H, W) at strictly increasing times
    ``t_s`` (T,), all later than ``after`` (None: no earlier sample).

    Returns (values as a float array, t (T,), prev (T,)) where ``prev[k]`` is the
    time of the sample before ``t[k]`` (``-inf`` for the very first one).
    """
    v = np.asarray(values)
    t = np.asarray(t_s, dtype=np.float64).reshape(-1)
    if v.ndim != 3 or v.shape[1:] != tuple(shape):
        raise ValueError(f"{name} must have shape (T, {shape[0]}, {shape[1]}), got {v.shape}")
    if len(t) != v.shape[0]:
        raise ValueError(f"t_s has {len(t)} times but {name} has {v.shape[0]} samples")
    if v.dtype.kind != "f":
        v = v.astype(np.float64)
    real_array(t, "t_s")
    prev = np.concatenate([[-np.inf if after is None else after], t[:-1]]) if len(t) else t
    if np.any(t <= prev):
        k = int(np.argmax(t <= prev))
        raise ValueError(f"time must increase strictly: sample {k} at t = {t[k]!r} s follows {prev[k]!r} s")
    return np.ascontiguousarray(v), t, prev
