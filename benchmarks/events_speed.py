"""Throughput of the whole per-step path: photoreceptor + noise, DVS, gradient (and RC).

Usage: python benchmarks/events_speed.py [--steps 200] [--repeat 5] [--preset davis346]
Input: a scikit-image photograph as a static scene at ~1 klux on the chip,
lit by a 100 Hz sinusoidal flicker of 50 % modulation, 10 us steps. Prints
best and median pixel-steps per second for each stage alone and for the path
pixel + DVS + gradient, with the event counts (events dominate the cost of
the event stages).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from skimage import data
from skimage.transform import resize

from gevsim.events import BrightnessEmulator, GradientEmulator
from gevsim.pixel import Photoreceptor, load_preset


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--preset", default="davis346")
    args = ap.parse_args()
    preset = load_preset(args.preset)
    print(f"{os.cpu_count()} cores; preset {preset.name}; {args.steps} steps of 10 us per call")
    for h, w in ((260, 346), (720, 1280)):
        steps = args.steps if h < 500 else max(20, args.steps // 5)
        scene = resize(data.camera().astype(float) / 255, (h, w)) * 0.9 + 0.05
        i_ref = preset.photoreceptor.cutoff_ref_photocurrent_a  # ~1 klux
        dt = 1e-5
        base = (i_ref * scene).astype(np.float32)
        rng = np.random.default_rng(0)
        pr = Photoreceptor((h, w), params=preset.photoreceptor, noise=preset.noise, rng=rng)
        pr.process(base[None], [dt])
        state = {"k": 2}

        def window():
            """The next ``steps`` samples of the flickering scene (computed outside the timers' stages)."""
            tw = dt * np.arange(state["k"], state["k"] + steps)
            state["k"] += steps
            return base[None] * (1 + 0.5 * np.sin(2 * np.pi * 100 * tw)).astype(np.float32)[:, None, None], tw

        v0 = pr.process(*window())  # compile, then keep going in time
        dvs = BrightnessEmulator((h, w), preset.events, rng=rng)
        grad = GradientEmulator((h, w), mismatch_sigma_ln=preset.events.threshold_mismatch_ln, rng=rng)
        grad_rc = GradientEmulator((h, w), rc=True, mismatch_sigma_ln=preset.events.threshold_mismatch_ln, rng=rng)
        tt = dt * np.arange(2, 2 + steps)
        for em in (dvs, grad, grad_rc):
            em.process(v0, tt)
        n = steps * h * w
        rows = []


        seconds = []
        for _ in range(args.repeat):
            c, tw = window()
            start = time.perf_counter()
            pr.process(c, tw)
            seconds.append(time.perf_counter() - start)
        rows.append(("photoreceptor + noise", min(seconds), float(np.median(seconds)), 0))
        for name, em in (("DVS", dvs), ("gradient", grad), ("gradient RC", grad_rc)):
            # Time only the emulator: run the pixel model first, outside the clock.
            seconds, counts = [], []
            for _ in range(args.repeat):
                c, tw = window()
                v = pr.process(c, tw)
                start = time.perf_counter()
                counts.append(len(em.process(v, tw)))
                seconds.append(time.perf_counter() - start)
            rows.append((name, min(seconds), float(np.median(seconds)), int(np.mean(counts))))
        seconds, counts = [], []
        for _ in range(args.repeat):
            c, tw = window()
            start = time.perf_counter()
            v = pr.process(c, tw)
            counts.append(len(dvs.process(v, tw)) + len(grad.process(v, tw)))
            seconds.append(time.perf_counter() - start)
        rows.append(("pixel + DVS + gradient", min(seconds), float(np.median(seconds)), int(np.mean(counts))))
        for name, best, med, count in rows:
            print(f"{w}x{h} {name:24s} best {n / best / 1e6:6.1f}  median {n / med / 1e6:6.1f} M pixel-steps/s"
                  f"   events/call {count}")


if __name__ == "__main__":
    main()
