"""Photoreceptor + noise throughput in pixel-steps per second.

Usage: python benchmarks/pixel_speed.py [--steps 200] [--repeat 5]
Prints the best and median of --repeat runs (after a warm-up that compiles the kernel)
for 346x260 and 1280x720, with the full noise model (shot, read, DSNU, PRNU),
with 1/f noise added, and noise-free.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numba
import numpy as np

from gevsim.pixel import NoiseParams, Photoreceptor, PhotoreceptorParams

CASES = {
    "full noise": NoiseParams(shot_noise=True, read_noise_v=1e-3, dark_current_a=3e-15, dark_current_spread=0.3,
                              prnu=0.01),
    "full + 1/f": NoiseParams(shot_noise=True, read_noise_v=1e-3, dark_current_a=3e-15, dark_current_spread=0.3,
                              prnu=0.01, flicker_noise_v=1e-3, flicker_noise_low_hz=1.0, flicker_noise_high_hz=1e3),
    "noise-free": NoiseParams(shot_noise=False, dark_current_a=3e-15),
}


def measure(shape, noise, steps, repeat, rng):
    pr = Photoreceptor(shape, params=PhotoreceptorParams(), noise=noise, rng=np.random.default_rng(0))
    current = (1e-12 * (0.5 + rng.random((steps,) + shape))).astype(np.float32)
    dt = 1e-5
    t = dt * np.arange(1, steps + 1)
    pr.process(current, t)  # warm-up (compiles on first use)
    seconds = []
    for k in range(repeat):
        start = time.perf_counter()
        pr.process(current, t + (k + 1) * steps * dt)
        seconds.append(time.perf_counter() - start)
    return current.size / min(seconds), current.size / float(np.median(seconds))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeat", type=int, default=15)
    args = ap.parse_args()
    rng = np.random.default_rng(1)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, numba {numba.__version__} "
          f"({numba.get_num_threads()} threads)")
    for shape in ((260, 346), (720, 1280)):
        steps = args.steps if shape[0] < 500 else max(20, args.steps // 10)
        for name, noise in CASES.items():
            best, median = measure(shape, noise, steps, args.repeat, rng)
            print(f"{shape[1]}x{shape[0]} {name:11s}: best {best / 1e6:6.1f}, median {median / 1e6:6.1f} "
                  f"M pixel-steps/s ({steps} steps per call)")


if __name__ == "__main__":
    main()
