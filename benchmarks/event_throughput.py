"""Event throughput where flicker lives: events/s and pixel-steps/s per stage on event-heavy inputs.

Usage: python benchmarks/event_throughput.py [--sizes 346x260,1280x720] [--threads 1,2] [--repeat 3]

Inputs (each a photocurrent sequence fed to the photoreceptor in chunks of ``--steps`` steps):

- ``flicker_pan``: a scikit-image texture (``brick``) panning 1 px per step under a 100 Hz
  square-wave lamp (+-25 %), sampled at 2 kHz (500 us steps), noise-free pixel: about half
  a DVS event per pixel per step, the issue 13 case (v2e's comparison input).
- ``noisy_lowlight``: the ``camera`` photograph at ~1 lux on the chip, davis346 noise on, 10 us
  steps: the gradient comparators chatter on pixel noise.
- ``sparse``: the ``camera`` photograph at ~1 klux with a 100 Hz 50 % sinusoid, 10 us steps
  (the sparse input of events_speed.py).

For each input, size and thread count it prints, per stage (photoreceptor alone; DVS, gradient,
CSDVS alone on the same voltages; the whole path photoreceptor + DVS + gradient), the median
seconds per chunk, pixel-steps/s and events/s. Numba's thread count is set per row
(``numba.set_num_threads``); the pool is started with the machine's cores. Not a timed test.
"""

from __future__ import annotations

import argparse
import os
import time

import numba
import numpy as np
from skimage import data
from skimage.transform import resize

from gevsim.events import BrightnessEmulator, CenterSurroundEmulator, GradientEmulator
from gevsim.pixel import Photoreceptor, load_preset


def inputs(h: int, w: int, steps: int, preset_ideal, preset_noisy):
    """name -> (preset, step_s, chunk(k) -> (photocurrent (T, H, W) float32, t_end_s (T,)))."""
    i_ref = preset_noisy.photoreceptor.cutoff_ref_photocurrent_a  # ~1 klux on the chip
    brick = resize(data.brick().astype(float) / 255, (h, 2 * w)) * 0.9 + 0.05
    camera = resize(data.camera().astype(float) / 255, (h, w)) * 0.9 + 0.05

    def pan(k):
        dt = 5e-4
        n = np.arange(k * steps, (k + 1) * steps)
        t = dt * (n + 1)
        lamp = np.where(np.mod(t * 100.0, 1.0) < 0.5, 1.25, 0.75)  # 100 Hz square wave, +-25 %
        frames = np.stack([np.roll(brick, -int(j), axis=1)[:, :w] for j in n]) * lamp[:, None, None]
        return (i_ref * frames).astype(np.float32), t

    def lowlight(k):
        dt = 1e-5
        t = dt * np.arange(k * steps + 1, (k + 1) * steps + 1)
        return np.broadcast_to((1e-3 * i_ref * camera).astype(np.float32), (steps, h, w)), t

    def sparse(k):
        dt = 1e-5
        t = dt * np.arange(k * steps + 1, (k + 1) * steps + 1)
        mod = (1 + 0.5 * np.sin(2 * np.pi * 100 * t)).astype(np.float32)
        return (i_ref * camera).astype(np.float32)[None] * mod[:, None, None], t

    return {"flicker_pan": (preset_ideal, pan), "noisy_lowlight": (preset_noisy, lowlight),
            "sparse": (preset_noisy, sparse)}


def measure(name, h, w, steps, repeat, preset, chunk):
    rng = np.random.default_rng(0)
    pr = Photoreceptor((h, w), params=preset.photoreceptor, noise=preset.noise, rng=rng)
    emulators = {"DVS": BrightnessEmulator((h, w), preset.events, rng=rng),
                 "gradient": GradientEmulator((h, w), mismatch_sigma_ln=preset.events.threshold_mismatch_ln,
                                              rng=rng),
                 "CSDVS": CenterSurroundEmulator((h, w), preset.events, rng=rng)}
    k = 0
    c, t = chunk(k)
    v = pr.process(c, t)  # compile everything, then keep going in time
    for em in emulators.values():
        em.process(v, t)
    rows = {}
    for _ in range(repeat):
        k += 1
        c, t = chunk(k)
        tick = time.perf_counter()
        v = pr.process(c, t)
        rows.setdefault("photoreceptor", []).append((time.perf_counter() - tick, 0))
        for label, em in emulators.items():
            tick = time.perf_counter()
            n = len(em.process(v, t))
            rows.setdefault(label, []).append((time.perf_counter() - tick, n))
    # The whole path on fresh emulators of the same kind (their state is the path's own).
    rng = np.random.default_rng(1)
    pr2 = Photoreceptor((h, w), params=preset.photoreceptor, noise=preset.noise, rng=rng)
    dvs2 = BrightnessEmulator((h, w), preset.events, rng=rng)
    grad2 = GradientEmulator((h, w), mismatch_sigma_ln=preset.events.threshold_mismatch_ln, rng=rng)
    c, t = chunk(0)
    v = pr2.process(c, t)
    dvs2.process(v, t)
    grad2.process(v, t)
    for j in range(repeat):
        c, t = chunk(j + 1)
        tick = time.perf_counter()
        v = pr2.process(c, t)
        n = len(dvs2.process(v, t)) + len(grad2.process(v, t))
        rows.setdefault("pixel + DVS + gradient", []).append((time.perf_counter() - tick, n))
    px = steps * h * w
    for label, samples in rows.items():
        s = float(np.median([a for a, _ in samples]))
        n = float(np.mean([b for _, b in samples]))
        print(f"  {name:15s} {w}x{h} {label:24s} {s:7.3f} s/chunk {px / s / 1e6:8.1f} M px-steps/s "
              f"{n / s / 1e6:8.2f} M events/s ({n / px:.3f} events per pixel-step)", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="346x260,1280x720")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--inputs", default="flicker_pan,noisy_lowlight,sparse")
    args = ap.parse_args()
    ideal, noisy = load_preset("davis346").ideal(), load_preset("davis346")
    print(f"{os.cpu_count()} cores, numba {numba.__version__} ({numba.config.THREADING_LAYER} layer requested), "
          f"chunks of {args.steps} steps, median of {args.repeat}")
    for size in args.sizes.split(","):
        w, h = (int(x) for x in size.split("x"))
        cases = inputs(h, w, args.steps, ideal, noisy)
        for threads in (int(x) for x in args.threads.split(",")):
            numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
            print(f"{w}x{h}, {threads} thread(s)")
            for name in args.inputs.split(","):
                preset, chunk = cases[name]
                measure(name, h, w, args.steps, args.repeat, preset, chunk)


if __name__ == "__main__":
    main()
