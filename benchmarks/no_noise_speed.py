"""The noise-free photoreceptor against the noisy one (issue 37, item 2: ``--no-noise`` ran 2.3x slower).

Usage: python benchmarks/no_noise_speed.py [--rounds 5] [--steps 200]

1. ``Photoreceptor.process`` of the davis346 preset and of its ideal (noise-free) copy at 346x260, 20 us
   steps of a photocurrent that changes every step, alternated (ABAB...) in this process: ns per pixel-step,
   best of ``--rounds``.
2. The cause: the output-pole row kernel (:func:`gevsim.pixel._cascade.smooth_row`, 1024 pixels, no noise)
   given a read-noise state that aliases its output state (what the photoreceptor kernel passed without read
   noise before the fix) or its own array (after), alternated: ns per pixel. The outputs are the same; with
   the alias LLVM's run-time overlap check fails and the loop runs scalar.
"""

from __future__ import annotations

import argparse
import math
import time

import numba
import numpy as np

from gevsim.pixel import Photoreceptor, load_preset
from gevsim.pixel._cascade import smooth_row


def photoreceptors(rounds: int, steps: int) -> None:
    h, w = 260, 346
    rng = np.random.default_rng(0)
    current = 1e-11 * (1 + rng.random((steps, h, w)))
    t = 2e-5 * np.arange(1, steps + 1)
    noisy = load_preset("davis346")
    presets = {"davis346 (noise)": noisy, "davis346 ideal (--no-noise)": noisy.ideal()}
    best = dict.fromkeys(presets, math.inf)
    for r in range(rounds + 1):  # round 0 compiles
        for name, p in presets.items():
            pr = Photoreceptor((h, w), params=p.photoreceptor, noise=p.noise, rng=np.random.default_rng(1))
            tick = time.perf_counter()
            pr.process(current, t)
            if r:
                best[name] = min(best[name], time.perf_counter() - tick)
    a, b = best.values()
    print(f"Photoreceptor.process, 346x260 x {steps} steps, {numba.get_num_threads()} numba threads, best of {rounds}:")
    for name, s in best.items():
        print(f"  {name:28s} {s / (steps * h * w) * 1e9:6.2f} ns/pixel-step")
    print(f"  noise-free / noisy time: {b / a:.2f}")


def row_kernel(rounds: int, reps: int = 2000) -> None:
    p = load_preset("davis346").photoreceptor
    n = 1024
    rng = np.random.default_rng(0)
    cur, gain, dark = 1e-11 * (1 + rng.random(n)), np.ones(n), np.full(n, 4e-15)
    z = np.zeros((4, n), np.float32)
    beta = 2 * math.pi * float(p.second_pole_hz or 0.0)
    b2 = math.exp(-beta * 2e-5)
    fc_per_a = p.cutoff_hz / p.cutoff_ref_photocurrent_a
    best = {"read state aliases v2 (before)": math.inf, "read state its own (after)": math.inf}
    for r in range(rounds + 1):
        for name in best:
            v1 = np.log(cur + dark)
            v2 = v1.copy()
            rd = v2 if "aliases" in name else np.zeros(n)
            out = np.empty(n, np.float32)
            args = (cur, gain, dark, v1, v2, rd, out, z[0], z[1], z[2], z[3], 2e-5, fc_per_a, p.max_cutoff_hz, 1.0,
                    0.0, 0.0, beta, b2, 1 - b2, False, (0.0,) * 6)
            tick = time.perf_counter()
            for _ in range(reps):
                smooth_row(*args)
            if r:
                best[name] = min(best[name], (time.perf_counter() - tick) / (reps * n))
    print(f"smooth_row without noise, {n} px, best of {rounds}:")
    for name, s in best.items():
        print(f"  {name:32s} {s * 1e9:6.2f} ns/pixel")
    a, b = best.values()
    print(f"  aliased / own: {a / b:.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--steps", type=int, default=200)
    args = ap.parse_args()
    photoreceptors(args.rounds, args.steps)
    row_kernel(args.rounds)


if __name__ == "__main__":
    main()
