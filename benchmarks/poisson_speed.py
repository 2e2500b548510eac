"""Speed of the Poisson solvers of gradient-event reconstruction: DCT vs SOR-100.

Usage: python benchmarks/poisson_speed.py [--repeat 7] [--sizes 240x180,346x260,640x480,1280x720]

For each size (width x height) the L_hat of a scikit-image photograph
(thresholds {4, 8, 16}/255, c = 3.6) is solved by the exact DCT solver
(float64 and float32; the 2-D ``dctn`` formulation for comparison) and by the paper's red-black SOR with k = 100 from a cold
start (numba kernel = ``method="sor"``, and the vectorised numpy reference).
Prints the best of ``--repeat`` solves in ms (after a warm-up) and the DCT
speed-up over each SOR.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
import scipy
from skimage import data
from skimage.transform import resize

from gevsim.events import GradientEmulator
from gevsim.events.gradient import PAPER_THRESHOLDS
from gevsim.reconstruct import PAPER_C, approximate_laplacian, dct, quantized_gradients, sor
from gevsim.reconstruct._sor import sor_numpy
from gevsim.reconstruct.poisson import _dct2


def best_ms(fn, repeat):
    fn()  # warm-up (numba compile, FFT plans, eigenvalue cache)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * min(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--sizes", default="240x180,346x260,640x480,1280x720")
    args = ap.parse_args()
    print(f"{os.cpu_count()} cores; numpy {np.__version__}, scipy {scipy.__version__}; best of {args.repeat}")
    print("| size | DCT f64 ms | DCT f32 ms | 2-D dctn f64 ms | SOR-100 numba ms | SOR-100 numpy ms "
          "| DCT speed-up vs numba | vs numpy |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for size in args.sizes.split(","):
        w, h = (int(n) for n in size.split("x"))
        img = resize(data.camera() / 255.0, (h, w))
        em = GradientEmulator((h, w), thresholds_ln=PAPER_THRESHOLDS)
        lhat = approximate_laplacian(*quantized_gradients(em.ternary_of(img), em.theta))
        lhat32 = lhat.astype(np.float32)
        b = PAPER_C * lhat
        slow = max(1, args.repeat // 3)
        t_dct = best_ms(lambda: dct(lhat, c=PAPER_C), args.repeat)
        t_dct32 = best_ms(lambda: dct(lhat32, c=PAPER_C), args.repeat)
        t_2d = best_ms(lambda: _dct2(lhat, c=PAPER_C), args.repeat)
        t_numba = best_ms(lambda: sor(lhat, c=PAPER_C, iterations=100), slow)
        t_numpy = best_ms(lambda: sor_numpy(np.zeros_like(b), b, 1.97, 100), slow)
        print(f"| {w}x{h} | {t_dct:.2f} | {t_dct32:.2f} | {t_2d:.2f} | {t_numba:.1f} | {t_numpy:.1f} "
              f"| {t_numba / t_dct:.0f}x | {t_numpy / t_dct:.0f}x |")


if __name__ == "__main__":
    main()
