"""Event collection in numbers: kernel and collection (gather) time per event, buffer bytes per
event, regrowths, for the DVS and gradient kernels on event-heavy inputs, 1 and 2 threads.

Usage: python benchmarks/event_collection.py [--sizes 346x260,1280x720] [--threads 1,2] [--chunks 6]

Inputs are the flickering pan, the noisy low-light scene and the PWM-lit office of
``event_throughput.py`` (its ``inputs``), fed to the photoreceptor once; the emulators then run chunk after chunk on those
voltages. "collected M ev/s" is events / seconds spent gathering the kernels' regions into the
time-ordered output (``EventBlocks.collect_s``): the collection rate issue 13 asks to be at least
50 M events/s per core. "buffer B/ev" is the largest buffers held (allocated, ``peak_buffer_bytes``)
over the events of that chunk. The first chunk (compilation, first guess of the buffer sizes) is
not counted. Not a timed test.
"""

from __future__ import annotations

import argparse
import os
import sys

import numba
import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from event_throughput import inputs  # noqa: E402

from gevsim.events import BrightnessEmulator, GradientEmulator  # noqa: E402
from gevsim.pixel import Photoreceptor, load_preset  # noqa: E402


def measure(name: str, h: int, w: int, steps: int, chunks: int, preset, chunk) -> None:
    rng = np.random.default_rng(0)
    pr = Photoreceptor((h, w), params=preset.photoreceptor, noise=preset.noise, rng=rng)
    inputs_ = [chunk(k) for k in range(chunks + 1)]
    volts = [pr.process(current, t) for current, t in inputs_]
    times = [t for _, t in inputs_]
    for label, em in (("DVS", BrightnessEmulator((h, w), preset.events, rng=rng)),
                      ("gradient", GradientEmulator((h, w), mismatch_sigma_ln=preset.events.threshold_mismatch_ln,
                                                    rng=rng))):
        em.process(volts[0], times[0])
        blk = em.blocks
        blk.kernel_s = blk.collect_s = 0.0
        blk.events = blk.peak_buffer_bytes = 0
        grown = blk.regrowths
        for v, t in zip(volts[1:], times[1:]):
            em.process(v, t)
        n = blk.events
        px = chunks * steps * h * w
        if n == 0:
            print(f"  {name:15s} {w}x{h} {label:9s} no events ({px / blk.kernel_s / 1e6:6.1f} M px-steps/s)")
            continue
        print(f"  {name:15s} {w}x{h} {label:9s} {n / px:6.3f} ev/px-step  kernel {blk.kernel_s / n * 1e9:6.1f} ns/ev "
              f"({px / blk.kernel_s / 1e6:6.1f} M px-steps/s)  collection {blk.collect_s / n * 1e9:5.1f} ns/ev = "
              f"{n / blk.collect_s / 1e6:6.1f} M ev/s collected  buffers {blk.peak_buffer_bytes / (n / chunks):5.1f} B/ev  "
              f"regrowths {blk.regrowths - grown}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="346x260,1280x720")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--chunks", type=int, default=6)
    ap.add_argument("--inputs", default="flicker_pan,noisy_lowlight,office")
    ap.add_argument("--cache", default="/tmp/gevsim-bench-cache", help="render cache of the office scene")
    args = ap.parse_args()
    ideal, noisy = load_preset("davis346").ideal(), load_preset("davis346")
    print(f"{os.cpu_count()} cores, numba {numba.__version__}, chunks of {args.steps} steps, {args.chunks} chunks")
    for size in args.sizes.split(","):
        w, h = (int(x) for x in size.split("x"))
        cases = inputs(args.inputs.split(","), h, w, args.steps, ideal, noisy, chunks=args.chunks + 1,
                       cache=args.cache, office_spp=8)
        for threads in (int(x) for x in args.threads.split(",")):
            numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
            print(f"{w}x{h}, {threads} thread(s)")
            for inp in cases:
                measure(inp.name, h, w, args.steps, args.chunks, inp.preset, inp.chunk)


if __name__ == "__main__":
    main()
