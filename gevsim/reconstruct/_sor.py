"""Red-black successive over-relaxation (SOR) kernels for the Poisson problem.

One iteration updates the "red" cells ((x + y) even, the solid circles of the
paper's Fig. "Parallelization of the SOR algorithm") and then the "black"
cells ((x + y) odd, the dashed circles), each cell as

    R(x, y) <- R(x, y) + beta * (R(x-1, y) + R(x+1, y) + R(x, y-1) + R(x, y+1)
                                 - 4 R(x, y) - b(x, y)),    beta = alpha / 4,

with b = c * L_hat. A neighbour outside the image is replaced by the cell
itself (reflecting / Neumann boundary), the boundary condition under which
A_X + A_Y of the paper equals the 5-point Laplacian. Lehtonen et al., Sec.
"Solving the Poisson's equation with successive over-relaxation".

:func:`sor_numba` is the production kernel; :func:`sor_numpy` is the same
update with vectorised red/black slices (reference and benchmark baseline).
Both use the same floating-point operation order.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _half_sweep(r, b, beta, parity):
    h, w = r.shape
    for y in range(h):
        for x in range((y + parity) % 2, w, 2):
            v = r[y, x]
            left = r[y, x - 1] if x > 0 else v
            right = r[y, x + 1] if x < w - 1 else v
            up = r[y - 1, x] if y > 0 else v
            down = r[y + 1, x] if y < h - 1 else v
            r[y, x] = v + beta * (left + right + up + down - 4.0 * v - b[y, x])


@njit(cache=True)
def _sor(r, b, beta, iterations):
    for _ in range(iterations):
        _half_sweep(r, b, beta, 0)  # red: (x + y) even
        _half_sweep(r, b, beta, 1)  # black: (x + y) odd


def sor_numba(r: np.ndarray, b: np.ndarray, alpha: float, iterations: int) -> np.ndarray:
    """``iterations`` red-black SOR sweeps on ``r`` (float64, C-contiguous) in place; returns ``r``."""
    _sor(r, b, 0.25 * alpha, iterations)
    return r


def sor_numpy(r: np.ndarray, b: np.ndarray, alpha: float, iterations: int) -> np.ndarray:
    """The same sweeps as :func:`sor_numba` with numpy slices (ghost cells = edge values)."""
    h, w = r.shape
    beta = 0.25 * alpha
    p = np.pad(r, 1, mode="edge")
    colours = (((0, 0), (1, 1)), ((0, 1), (1, 0)))  # (y parity, x parity) of red, then black cells
    for _ in range(iterations):
        for cells in colours:
            for py, px in cells:
                ys, xs = slice(1 + py, h + 1, 2), slice(1 + px, w + 1, 2)
                v = p[ys, xs]
                left, right = p[ys, slice(px, w, 2)], p[ys, slice(2 + px, w + 2, 2)]
                up, down = p[slice(py, h, 2), xs], p[slice(2 + py, h + 2, 2), xs]
                p[ys, xs] = v + beta * (left + right + up + down - 4.0 * v - b[py::2, px::2])
            # Refresh the ghost cells (reflecting boundary) for the next half-sweep.
            p[0, 1:-1], p[-1, 1:-1] = p[1, 1:-1], p[-2, 1:-1]
            p[:, 0], p[:, -1] = p[:, 1], p[:, -2]
    r[...] = p[1:-1, 1:-1]
    return r
