"""Tridiagonal (Thomas) solves for the Neumann Poisson problem after a 1-D DCT.

After a DCT-II along axis 1 with eigenvalues lam_u = 2 cos(pi u / W) - 2, the
5-point Neumann Laplacian decouples into one tridiagonal system per column u
along axis 0:

    r[y-1] + (lam_u - 2) r[y] + r[y+1] = f[y]   (rows 0 and H-1: lam_u - 1 on the
                                                 diagonal, the reflected neighbour)

Sub- and super-diagonals are 1, so the LU factorisation of column u is a single
array m[y, u] = 1 / (b[y] - m[y-1, u]) (m[-1] = 0) that depends only on the
shape; it is cached, and a solve is two sweeps vectorised across the columns.
The u = 0 system is singular (pure Neumann); its column is solved separately.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import njit

from gevsim import _portable as pm


@functools.lru_cache(maxsize=32)
def factor(shape: tuple[int, int], dtype: str) -> np.ndarray:
    """m[y, u] of the LU factorisation for an (H, W) grid (column u = 0 left at 0)."""
    h, w = shape
    lam = 2.0 * pm.cos(np.pi * np.arange(w) / w) - 2.0
    m = np.zeros((h, w))
    prev = np.zeros(w)
    for y in range(h):
        diag = lam - (1.0 if y in (0, h - 1) else 2.0) if h > 1 else lam
        with np.errstate(divide="ignore"):
            prev = 1.0 / (diag - prev)
        m[y] = prev
    m[:, 0] = 0.0
    m = m.astype(dtype)
    m.flags.writeable = False
    return m


@njit(cache=True)
def solve_columns(f, m, scale):
    """Solve every column u >= 1 of ``f`` in place (right-hand side scale * f)."""
    h, w = f.shape
    for u in range(1, w):
        f[0, u] = scale * f[0, u] * m[0, u]
    for y in range(1, h):
        for u in range(1, w):
            f[y, u] = (scale * f[y, u] - f[y - 1, u]) * m[y, u]
    for y in range(h - 2, -1, -1):
        for u in range(1, w):
            f[y, u] = f[y, u] - m[y, u] * f[y + 1, u]
    return f
