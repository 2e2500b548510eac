"""Results of an emulation: the run's summary (:class:`RunSummary`, what :func:`gevsim.emulation.run`
returns) and per-stream statistics read back from its file in frame-sized windows, bounded memory
(:class:`StreamStats`, :func:`summarize`)."""

from __future__ import annotations

import dataclasses
import os
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from gevsim.emulation import layout
from gevsim.events.statistics import event_probability, event_rates
from gevsim.io import EventReader, event_reader

BATCH_FRAMES = 64  # frame intervals per read at most (fewer when they hold more than event_reader.WINDOW_EVENTS events)

__all__ = ["RunSummary", "StreamStats", "summarize"]


class _Fields:
    """Read-only ``result["field"]`` on a frozen result dataclass, for code written against the
    dicts these results used to be; :meth:`as_dict` gives a JSON-ready copy."""

    if TYPE_CHECKING:  # the subclasses are dataclasses
        __dataclass_fields__: ClassVar[dict[str, dataclasses.Field[Any]]]

    def __getitem__(self, key: str) -> Any:
        if key not in {f.name for f in dataclasses.fields(self)}:
            raise KeyError(key)
        return getattr(self, key)

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class RunSummary(_Fields):
    """What one emulation run wrote and how long it took (:func:`gevsim.emulation.run`).

    Attributes
    ----------
    out : the HDF5 file written.
    width, height : sensor size in pixels.
    steps : pixel-model time steps.
    duration_s : emulated time.
    frames : ground-truth frames written.
    counts : events per stream (HDF5 group name).
    rates_hz : events per second per stream.
    render_s, pixel_s, total_s : seconds spent rendering (or loading) the basis, in the pixel model (each step's
        photocurrent mix and the photoreceptor with its noise), in all.
    event_s : seconds spent in each emulator, by its name (its readout: ``stage_s["readout"]``).
    render_noise : achieved render noise (:func:`gevsim.render.convergence.summarize_quality`).
    pixel_steps_per_s : pixel-model throughput (pixel-steps over ``pixel_s``).
    readout : each stream's readout counts (:meth:`gevsim.events.readout.Readout.summary`), as in the
        file's ``readout_json`` attribute.
    chunk_steps : the steps of each chunk (the config's, or the memory budget's:
        :func:`gevsim.resources.budget_chunk_steps`).
    stage_s : seconds per stage, in the order they run (:data:`gevsim.emulation.stepping.STAGES`, each emulator
        by its name): ``render`` (the basis, rendered or loaded, and the checks), ``start`` (the pixel chain,
        settled and burnt in), ``ground_truth`` (the frames), ``mix`` (each step's photocurrent),
        ``photoreceptor`` (with its noise), the emulators, ``readout``, ``hdf5`` (appending events, closing the
        file) and ``before_commit`` (the caller's check of the finished file). Their sum is at most ``total_s``
        (what is left: progress reports, building this summary).
    """

    out: str
    width: int
    height: int
    steps: int
    duration_s: float
    frames: int
    counts: dict[str, int]
    rates_hz: dict[str, float]
    render_s: float
    pixel_s: float
    event_s: dict[str, float]
    render_noise: dict[str, Any]
    pixel_steps_per_s: float
    total_s: float
    readout: dict[str, dict[str, Any]]
    chunk_steps: int
    stage_s: dict[str, float]


@dataclasses.dataclass(frozen=True)
class StreamStats(_Fields):
    """Statistics of one event stream of an emulation file (:func:`summarize`).

    Attributes
    ----------
    count : events in the stream.
    rates_hz : events per second: ``total``, per polarity (``"+1"``, ``"-1"``) or axis (``"x"``,
        ``"y"``), and ``per_pixel_hz``.
    event_probability : mean probability of an event per ground-truth frame interval, as Lehtonen
        et al. count it (NaN without frames).
    """

    count: int
    rates_hz: dict[str, float]
    event_probability: float


def _frame_batches(r: EventReader, stream: str, frame_t: np.ndarray) -> list[tuple[int, int]]:
    """Consecutive runs ``(a, b)`` of frame intervals (frame_t[a], frame_t[b]], each of at most
    BATCH_FRAMES intervals and event_reader.WINDOW_EVENTS events (one interval however many it holds)."""
    if len(frame_t) < 2:
        return []
    lo, hi = r.index_bounds(stream, np.asarray(frame_t, np.int64) + 1)
    out, a = [], 0
    while a < len(frame_t) - 1:
        b = a + 1
        while b + 1 < len(frame_t) and b - a < BATCH_FRAMES and hi[b + 1] - lo[a] <= event_reader.WINDOW_EVENTS:
            b += 1
        out.append((a, b))
        a = b
    return out


def summarize(path: str | os.PathLike, *, frames: str = layout.LOG_PHOTOCURRENT) -> dict[str, StreamStats]:
    """Per stream: event count, rates (total, per polarity/axis, per pixel) and the mean
    event probability per ground-truth frame interval as Lehtonen et al. count it."""
    out = {}
    with EventReader(path) as r:
        w, h = r.width, r.height
        duration = r.t_end_us / 1e6
        frame_t = r.array(f"/frames/{frames}/t") if frames in r.frame_names else np.zeros(0, np.int64)
        for stream in r.streams:
            probabilities = []
            for a, b in _frame_batches(r, stream, frame_t):
                ft = frame_t[a:b + 1]
                # Events in (ft[0], ft[-1]]: read [ft[0] + 1, ft[-1] + 1) in microseconds.
                ev = r.read(stream, int(ft[0]) + 1, int(ft[-1]) + 1)
                probabilities.append(event_probability(ev, ft, width=w, height=h))
            # Rates from windows of at most event_reader.WINDOW_EVENTS events, so memory stays bounded.
            totals: dict[str, float] = {}
            count = 0
            for start, end in r.windows(stream, 0, int(r.t_end_us) + 1):
                ev = r.read(stream, start, end)
                count += len(ev)
                for key, rate in event_rates(ev, 1.0).items():  # per second of 1 s = counts
                    totals[key] = totals.get(key, 0.0) + rate
            rates = {k: v / duration for k, v in totals.items()}
            rates["per_pixel_hz"] = rates["total"] / (w * h)
            p = np.concatenate(probabilities) if probabilities else np.zeros(0)
            out[stream] = StreamStats(count=count, rates_hz=rates,
                                      event_probability=float(p.mean()) if p.size else float("nan"))
    return out
