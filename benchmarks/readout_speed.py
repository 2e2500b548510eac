"""The readout's cost per requested event on a flicker-heavy stream (issue 37, item 2).

The DVS events of ``event_throughput.py``'s ``flicker_pan`` (a texture panning 1 px per 500 us frame under a
100 Hz lamp, noise-free pixel, ``EventParams()``) at 346x260: ~6 million crossings in 5 chunks of 50 frames,
about four times what a DAVIS346's 12 Meps bus reads. They go through the davis346 preset's readout (latency
and jitter, then the row-burst arbiter at 12 Meps), chunk by chunk, twice; the second pass is reported:
nanoseconds per requested event for the latency stage and for the arbiter (with its conversions), and a
SHA-256 of what was delivered, so that two codes can be compared on the same input (``git stash`` between
runs). Usage: ``python benchmarks/readout_speed.py [--size 346x260]``.
"""

from __future__ import annotations

import argparse
import hashlib
import time

import numpy as np
from event_throughput import DN_FLOOR, inputs

from gevsim.events import BrightnessEmulator
from gevsim.events.readout import Readout
from gevsim.pixel import EventParams, load_preset


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="346x260")
    args = ap.parse_args()
    w, h = (int(x) for x in args.size.split("x"))
    steps, chunks = 50, 6
    preset = load_preset("davis346")
    (pan,) = inputs(["flicker_pan"], h, w, steps, preset, preset, chunks=chunks, cache="", office_spp=1)
    dvs = BrightnessEmulator((h, w), EventParams(), rng=np.random.default_rng(0))
    streams = []
    for k in range(chunks):
        current, t = pan.chunk(k)
        dn = 255.0 * current / preset.photoreceptor.cutoff_ref_photocurrent_a
        events = dvs.process(np.log(np.maximum(dn, DN_FLOOR)).astype(np.float32), t)
        if k:
            streams.append((events, float(t[-1]) * 1e6))
    requested = sum(len(e) for e, _ in streams)
    for rep in range(2):
        readout = Readout(preset.readout, key=1, shape=(h, w))
        seconds = {name: 0.0 for name in [*readout.stages, "arbiter"]}
        digest = hashlib.sha256()
        for k, (events, until) in enumerate(streams):
            first = readout.requested
            readout.requested += len(events)
            horizon = until if k < len(streams) - 1 else None
            for name, stage in readout.stages.items():
                tick = time.perf_counter()
                events, horizon = stage.process(events, horizon, first)
                seconds[name] += time.perf_counter() - tick
            if readout.arbiter is None:
                from gevsim.events.readout import _ArbiterState

                readout.arbiter = _ArbiterState((h, w), axes=1)
            tick = time.perf_counter()
            out = readout.arbiter.serve(readout, events, horizon=horizon, end_us=None)
            seconds["arbiter"] += time.perf_counter() - tick
            digest.update(out.tobytes())
        if rep:
            print(f"{w}x{h}: {requested} requested; " + ", ".join(
                f"{name} {s / requested * 1e9:.1f} ns" for name, s in seconds.items())
                + f", total {sum(seconds.values()) / requested * 1e9:.1f} ns per requested event; "
                f"delivered sha256 {digest.hexdigest()[:12]}")


if __name__ == "__main__":
    main()
