"""Cost of CPU-independent arithmetic (issue 21): gevsim._portable against numpy/BLAS, side by side.

Each pair runs alternately in one process (medians of ``--repeat`` calls after a warm-up), so the
ratios hold on a shared machine even where absolute times scatter.

    .venv/bin/python benchmarks/portable_speed.py [--repeat 15]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from gevsim import _portable as pm


def median_s(f, repeat):
    f()
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=15)
    a = ap.parse_args()
    rng = np.random.default_rng(0)
    x = rng.uniform(-20.0, 20.0, 1_000_000)
    pos = np.abs(x) + 1e-3
    cases = [
        ("exp, 1e6 float64", lambda: np.exp(x), lambda: pm.exp(x)),
        ("log, 1e6 float64", lambda: np.log(pos), lambda: pm.log(pos)),
        ("sin, 1e6 float64", lambda: np.sin(x), lambda: pm.sin(x)),
    ]
    for h, w in ((260, 346), (720, 1280)):
        for k in (2, 4):
            b32 = rng.random((k, h * w), dtype=np.float32)
            wts = rng.random((50, k))
            cases.append((f"mix 50 steps x {k} groups, {w}x{h} float32",
                          lambda b32=b32, wts=wts: wts.astype(np.float32) @ b32,
                          lambda b32=b32, wts=wts: pm.weighted_sum(wts, b32, dtype=np.float32)))
    print(f"{'operation':44s} {'numpy/BLAS ms':>13s} {'portable ms':>11s} {'ratio':>6s}")
    for name, ref, new in cases:
        r, n = median_s(ref, a.repeat), median_s(new, a.repeat)
        print(f"{name:44s} {r * 1e3:13.2f} {n * 1e3:11.2f} {n / r:6.2f}")


if __name__ == "__main__":
    main()
