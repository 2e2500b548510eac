"""Statistics of an emulation file, read back in frame-sized windows (bounded memory)."""

from __future__ import annotations

import os

import numpy as np

from gevsim.emulation import layout
from gevsim.events.statistics import event_probability, event_rates
from gevsim.io import EventReader

BATCH_FRAMES = 64
WINDOW_US = 100_000  # events counted 0.1 s at a time


def summarize(path: str | os.PathLike, *, frames: str = layout.LOG_PHOTOCURRENT) -> dict:
    """Per stream: event count, rates (total, per polarity/axis, per pixel) and the mean
    event probability per ground-truth frame interval as Lehtonen et al. count it."""
    out = {}
    with EventReader(path) as r:
        w, h = r.width, r.height
        duration = r.t_end_us / 1e6
        frame_t = r.array(f"/frames/{frames}/t") if frames in r.frame_names else np.zeros(0, np.int64)
        for stream in r.streams:
            probabilities = []
            for a in range(0, max(len(frame_t) - 1, 0), BATCH_FRAMES):
                ft = frame_t[a:a + BATCH_FRAMES + 1]
                # Events in (ft[0], ft[-1]]: read [ft[0] + 1, ft[-1] + 1) in microseconds.
                ev = r.read(stream, int(ft[0]) + 1, int(ft[-1]) + 1)
                probabilities.append(event_probability(ev, ft, width=w, height=h))
            # Rates from windows of WINDOW_US, so memory stays bounded for any duration.
            totals, count = {}, 0
            for start in range(0, int(r.t_end_us) + 1, WINDOW_US):
                ev = r.read(stream, start, start + WINDOW_US)
                count += len(ev)
                for key, rate in event_rates(ev, 1.0).items():  # per second of 1 s = counts
                    totals[key] = totals.get(key, 0.0) + rate
            rates = {k: v / duration for k, v in totals.items()}
            rates["per_pixel_hz"] = rates["total"] / (w * h)
            p = np.concatenate(probabilities) if probabilities else np.zeros(0)
            out[stream] = {"count": count, "rates_hz": rates,
                           "event_probability": float(p.mean()) if p.size else float("nan")}
    return out
