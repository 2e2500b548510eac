"""Seconds of ``gevsim.events.stationary.draw_levels`` (each DVS pixel's start level from its stationary law)
for N pixels with spread thresholds, noise, Rice rates, correlations and leaks: the start's largest cost at
1280x720 (N = 921,600). Prints the levels' SHA-256 (prefix) and saves them, so that two codes can be compared
on the same input (run it alternately on each: ``git stash`` between runs).

Usage: python benchmarks/start_levels.py [N] [TAG]   (the levels go to /tmp/levels_TAG.npy)
"""

from __future__ import annotations

import hashlib
import sys
import time

import numpy as np

from gevsim.events.stationary import draw_levels


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 100_000
    tag = sys.argv[2] if len(sys.argv) > 2 else "now"
    rng = np.random.default_rng(0)
    th_on = 0.2 + 0.03 * rng.standard_normal(n)
    th_off = 0.2 + 0.03 * rng.standard_normal(n)
    sigma = np.abs(0.02 + 0.01 * rng.standard_normal(n))
    nu = 500 + 400 * rng.random(n)
    rho = rng.random(n)
    drift = 0.03 + 0.1 * rng.random(n)
    uniform = rng.random(n)
    out = np.empty(n)
    args = (th_on, th_off, sigma, nu, rho, drift)
    draw_levels(*(a[:10] for a in args), 0.01, uniform[:10], out[:10])  # compile (or load) first
    tick = time.perf_counter()
    draw_levels(*args, 0.01, uniform, out)
    seconds = time.perf_counter() - tick
    np.save(f"/tmp/levels_{tag}.npy", out)
    print(f"{n} px: {seconds:.3f} s, {seconds / n * 1e6:.2f} us/px; levels sha256 "
          f"{hashlib.sha256(out.tobytes()).hexdigest()[:12]}")


if __name__ == "__main__":
    main()
