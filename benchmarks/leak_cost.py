"""Cost of the light-dependent leak in the DVS kernel (issue 23): the same 346x260 x 500-step chunk with
``leak_light_hz_per_a`` = 0 and 3e8, alternately, 5 times; medians and their ratio.

    NUMBA_NUM_THREADS=1 .venv/bin/python benchmarks/leak_cost.py
"""

from __future__ import annotations

import time

import numpy as np

from gevsim.events import BrightnessEmulator
from gevsim.pixel.params import EventParams


def main() -> None:
    shape, steps = (260, 346), 500
    rng = np.random.default_rng(0)
    v = (-27.6 + np.cumsum(0.01 * rng.standard_normal((steps,) + shape), axis=0)).astype(np.float32)
    t = 2e-5 * np.arange(1, steps + 1)
    times: dict[bool, list[float]] = {False: [], True: []}
    n = 0
    for _ in range(5):
        for light in (False, True):
            p = EventParams(leak_rate_hz=0.05, leak_light_hz_per_a=3e8 if light else 0.0)
            em = BrightnessEmulator(shape, p, rng=np.random.default_rng(1))
            em.process(v[:2], t[:2])
            tick = time.perf_counter()
            n = len(em.process(v[2:], t[2:]))
            times[light].append(time.perf_counter() - tick)
    a, b = float(np.median(times[False])), float(np.median(times[True]))
    print(f"median s per chunk: without light leak {a:.4f}, with {b:.4f}, ratio {b / a:.3f} ({n} events)")


if __name__ == "__main__":
    main()
