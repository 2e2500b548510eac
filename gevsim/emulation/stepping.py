"""A run's time loop (:func:`stream_chunks`) and its clock per stage (:class:`StageClock`, issue 37).

The loop steps the pixel chain over the run in chunks of ``chunk_steps`` steps: each chunk's
photocurrent (the mix of the photocurrent basis, :func:`~gevsim.emulation.start.held_photocurrent`),
the photoreceptor with its noise, each emulator, its readout, and the events appended to the file.
Every stage is timed (:data:`STAGES`), so a run's summary says where its time went.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from gevsim.emulation import layout
from gevsim.emulation.bridging import Bridging, process_kwargs
from gevsim.emulation.config import EmulationConfig
from gevsim.emulation.emulators import EMULATORS
from gevsim.emulation.photocurrent import Setup
from gevsim.emulation.start import held_photocurrent, refine, step_grid
from gevsim.io import EventWriter
from gevsim.pixel import Photoreceptor

#: The stages of a run in the order they run (:attr:`gevsim.emulation.summary.RunSummary.stage_s`); the
#: emulators', by name, come between ``photoreceptor`` and ``readout`` (:func:`stage_names`).
STAGES = ("render", "start", "ground_truth", "mix", "photoreceptor", "readout", "hdf5", "before_commit")


def stage_names(emulators: Iterable[str]) -> tuple[str, ...]:
    """:data:`STAGES` with the emulators' names after ``photoreceptor``."""
    k = STAGES.index("readout")
    return (*STAGES[:k], *emulators, *STAGES[k:])


class StageClock:
    """Seconds per stage, taken as laps: ``t = clock.lap("mix", t)`` adds the time since ``t`` to the stage and
    returns now, so that consecutive laps cover a run without gaps or overlaps. A callable wrapped by
    :meth:`timed` counts to its own stage, and not to the lap it runs in."""

    def __init__(self, stages: Iterable[str]):
        self.seconds: dict[str, float] = dict.fromkeys(stages, 0.0)
        self._inner = 0.0  # seconds of timed() calls since the last lap

    def lap(self, stage: str, since: float) -> float:
        now = time.perf_counter()
        self.seconds[stage] = self.seconds.get(stage, 0.0) + (now - since - self._inner)
        self._inner = 0.0
        return now

    def timed(self, stage: str, fn: Callable[[Any], Any]) -> Callable[[Any], Any]:
        def call(arg: Any) -> Any:
            tick = time.perf_counter()
            try:
                return fn(arg)
            finally:
                spent = time.perf_counter() - tick
                self.seconds[stage] = self.seconds.get(stage, 0.0) + spent
                self._inner += spent
        return call


def stream_chunks(config: EmulationConfig, setup: Setup, wr: EventWriter, pr: Photoreceptor, emulators: dict,
                  readouts: dict, *, grid_waveforms: tuple, sub: int, chunk_steps: int, end_us: int, counts: dict,
                  clock: StageClock, since: float, progress: Callable[[int, int], None] | None,
                  bridging: Bridging | None = None) -> float:
    """Step the chain over the run in chunks of ``chunk_steps`` steps and append each stream's events to ``wr``
    (counting them in ``counts``), timing each stage on ``clock`` from ``since``; returns the last lap's end.
    ``bridging``: the crossing rule's noise-free twin (its time counts to the photoreceptor's)."""
    n_steps = config.time.steps(setup.duration_s)
    t_end_all = config.step_s * np.arange(1, n_steps + 1)
    chunks = range(0, n_steps, chunk_steps)
    t = since
    for c, a in enumerate(chunks):
        b = min(a + chunk_steps, n_steps)
        t0 = t_end_all[a] - config.step_s
        t_end = step_grid(grid_waveforms, t0, refine(t_end_all[a:b], t0, sub))
        current = held_photocurrent(setup, t0, t_end)
        t = clock.lap("mix", t)
        v = pr.process(current, t_end)
        bridge = bridging.bridge(current, t_end) if bridging is not None else None
        del current  # before the emulators' buffers: a chunk's photocurrent and output are its largest arrays
        t = clock.lap("photoreceptor", t)
        until = None if b == n_steps else math.floor(t_end[-1] * 1e6)
        for name, em in emulators.items():
            made = em.process(v, t_end, **process_kwargs(EMULATORS[name].bridges, bridge))
            t = clock.lap(name, t)
            events = readouts[name].process(made, end_us=end_us, until_us=until)
            t = clock.lap("readout", t)
            stream = EMULATORS[name].stream
            if c == 0 and EMULATORS[name].decodes:  # decoding starts from it
                layout.write_initial_state(wr, name, em.initial_state)
            wr.append(stream, events)
            counts[stream] += len(events)
            t = clock.lap("hdf5", t)
        if progress:
            progress(c + 1, len(chunks))
            t = time.perf_counter()  # the caller's: no stage of the run
    return t
