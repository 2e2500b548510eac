"""The box-filter kernel of pose reuse (:func:`gevsim.render.rotation.box_resample`): for each target
rectangle, the sum of the source cells it overlaps weighted by (overlap area / rectangle area)^power.

Each rectangle is summed alone, over its cells row by row and left to right, in float64, so the result
does not depend on the thread count; numba runs the rectangles in parallel.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(cache=True, parallel=True)
def box_sums(flat: np.ndarray, x0: np.ndarray, y0: np.ndarray, x1: np.ndarray, y1: np.ndarray,
             power: int) -> np.ndarray:  # pragma: no cover - compiled
    """(N, V) float64 sums over the (Hc, Wc, V) cell image ``flat`` for the N rectangles
    [x0, x1] x [y0, y1] (cell units); an overlap outside the grid takes the nearest edge cell."""
    hc, wc, nv = flat.shape
    n = x0.size
    out = np.zeros((n, nv))
    for i in prange(n):
        a, b, c, d = x0[i], y0[i], x1[i], y1[i]
        area = (c - a) * (d - b)
        for cy in range(int(math.floor(b)), int(math.ceil(d))):
            wy = min(d, cy + 1.0) - max(b, float(cy))
            if wy <= 0.0:
                continue
            iy = min(max(cy, 0), hc - 1)
            for cx in range(int(math.floor(a)), int(math.ceil(c))):
                wx = min(c, cx + 1.0) - max(a, float(cx))
                if wx <= 0.0:
                    continue
                ix = min(max(cx, 0), wc - 1)
                wgt = wy * wx / area
                if power == 2:
                    wgt = wgt * wgt
                for v in range(nv):
                    out[i, v] += wgt * flat[iy, ix, v]
    return out
