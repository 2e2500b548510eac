"""Center-surround brightness events (CSDVS; Delbruck, Li, Graca & McReynolds,
"Utility and feasibility of a center surround event camera", ICIP 2022).

The surround is the photoreceptor output diffused by a resistive grid with
space constant ``surround_length_px`` (in pixels) and low-pass filtered in
time with ``surround_tau_s``; DVS events are emitted on centre minus
surround. The grid is solved exactly, separably: (1 - l^2 D_xx) then
(1 - l^2 D_yy) with reflecting (Neumann) borders, each a tridiagonal system
solved by the Thomas algorithm with precomputed coefficients. Separable
diffusion approximates the 2-D grid (whose kernel is a Bessel K0) by a
product of 1-D exponential kernels exp(-|x|/l').
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numba import njit, prange
from numpy.typing import ArrayLike

from gevsim import _portable as pm
from gevsim._validate import real
from gevsim.events.brightness import BrightnessEmulator
from gevsim.pixel.params import REFERENCE_TEMPERATURE_K, EventParams

COLUMN_BLOCK = 16  # columns per parallel work item of the y solves
ROW_BLOCK = 8  # rows per parallel work item of the x solves
#: The longest surround space constant: 10^4 px, beyond any sensor's size (the surround is then the frame's mean).
#: The diffuser's solve uses its square; 1e300 px overflowed it to NaN after the render.
MAX_SURROUND_LENGTH_PX = 1e4


def thomas_coefficients(n: int, c: float) -> tuple[np.ndarray, np.ndarray]:
    """Forward-elimination factors of (1 + 2c) s_i - c (s_{i-1} + s_{i+1}) = v_i with
    reflecting ends ((1 + c) on the diagonal of the first and last rows).

    Returns (inv_denominator, upper) so that d_i = (v_i + c d_{i-1}) * inv_den_i and
    s_i = d_i + upper_i s_{i+1}.
    """
    diag = np.full(n, 1.0 + 2.0 * c)
    diag[0] = diag[-1] = 1.0 + c
    if n == 1:
        diag[0] = 1.0
    inv_den = np.empty(n)
    upper = np.zeros(n)
    prev_upper = 0.0
    for i in range(n):
        den = diag[i] - c * prev_upper
        inv_den[i] = 1.0 / den
        upper[i] = c / den if i < n - 1 else 0.0
        prev_upper = upper[i]
    return inv_den, upper


@njit(inline="always")
def _solve(line, out, inv_den, upper, c):
    n = line.shape[0]
    d = 0.0
    for i in range(n):
        d = (line[i] + c * d) * inv_den[i]
        out[i] = d
    for i in range(n - 2, -1, -1):
        out[i] = out[i] + upper[i] * out[i + 1]


@njit(inline="always")
def _solve_lines(buf, m, d, inv_den, upper, c):
    """_solve on the first ``m`` columns of ``buf`` (length, block) at once, in place: the
    recurrences of independent lines run side by side (vectorised) instead of one
    latency-bound chain each; each line's arithmetic is that of _solve."""
    for j in range(m):
        d[j] = 0.0
    for i in range(buf.shape[0]):
        for j in range(m):
            d[j] = (buf[i, j] + c * d[j]) * inv_den[i]
            buf[i, j] = d[j]
    for i in range(buf.shape[0] - 2, -1, -1):
        for j in range(m):
            buf[i, j] = buf[i, j] + upper[i] * buf[i + 1, j]


@njit(parallel=True, cache=True)
def diffuse(image: np.ndarray, out: np.ndarray, inv_x: np.ndarray, up_x: np.ndarray, inv_y: np.ndarray,
            up_y: np.ndarray, c: float) -> None:
    """Separable resistive-grid diffusion of one (H, W) image into ``out``."""
    h, w = image.shape
    tmp = np.empty((h, w))
    for y in prange(h):
        _solve(image[y].astype(np.float64), tmp[y], inv_x, up_x, c)
    for x in prange(w):
        col = np.empty(h)
        _solve(tmp[:, x].copy(), col, inv_y, up_y, c)
        for y in range(h):
            out[y, x] = col[y]


@njit(parallel=True, cache=True)
def centre_minus_surround(v: np.ndarray, decay: np.ndarray, surround: np.ndarray, inv_x: np.ndarray,
                          up_x: np.ndarray, inv_y: np.ndarray, up_y: np.ndarray, c: float, diff: np.ndarray) -> None:
    """For each step k: target = diffuse(v[k]); surround <- target + decay[k] (surround - target)
    (exact first-order low-pass for held input); diff[k] = v[k] - surround. ``surround`` is
    updated in place (the state carried across chunks).

    Two parallel loops per call, each walking all T steps inside: rows (the x solves of every
    step, written to ``diff``), then columns (the y solve, the temporal low-pass and the
    difference, in place in ``diff``). A parallel loop per step would cost a fork and a join
    of the thread pool per step, which on a loaded machine (threads descheduled at the join)
    made CSDVS 40-120x slower (issue 12). The arithmetic is the per-step kernel's, operation for
    operation, so results are bit-identical to it."""
    t_steps, h, w = v.shape
    ngroups = (h + ROW_BLOCK - 1) // ROW_BLOCK
    for g in prange(ngroups):
        # ROW_BLOCK rows at once, transposed into ``buf`` (one row per column) for _solve_lines.
        y0 = g * ROW_BLOCK
        ny = min(h, y0 + ROW_BLOCK) - y0
        buf = np.empty((w, ROW_BLOCK))
        d = np.empty(ROW_BLOCK)
        for k in range(t_steps):
            for j in range(ny):
                for x in range(w):
                    buf[x, j] = np.float64(v[k, y0 + j, x])
            _solve_lines(buf, ny, d, inv_x, up_x, c)
            for j in range(ny):
                for x in range(w):
                    diff[k, y0 + j, x] = buf[x, j]
    nblocks = (w + COLUMN_BLOCK - 1) // COLUMN_BLOCK
    for b in prange(nblocks):
        # COLUMN_BLOCK neighbouring columns at once (memory read along rows), by _solve_lines.
        x0 = b * COLUMN_BLOCK
        nx = min(w, x0 + COLUMN_BLOCK) - x0
        col = np.empty((h, COLUMN_BLOCK))
        d = np.empty(COLUMN_BLOCK)
        for k in range(t_steps):
            for y in range(h):
                for j in range(nx):
                    col[y, j] = diff[k, y, x0 + j]
            _solve_lines(col, nx, d, inv_y, up_y, c)
            a = decay[k]
            for y in range(h):
                for j in range(nx):
                    x = x0 + j
                    target = col[y, j]
                    s = target + a * (surround[y, x] - target)
                    surround[y, x] = s
                    diff[k, y, x] = np.float64(v[k, y, x]) - s


class CenterSurroundEmulator:
    """CSDVS over (H, W) pixels; state kept across chunks.

    Parameters
    ----------
    shape : (H, W).
    params : event-circuit parameters (thresholds, mismatch, refractory, leak).
    surround_length_px : space constant of the diffuser, in pixels.
    surround_tau_s : time constant of the surround (0: instantaneous).
    rng : draws the fixed patterns of the event circuit.
    cold_start, temperature_k : as :class:`~gevsim.events.BrightnessEmulator` (the light-dependent
        leak is left out: the signal is a difference, not a photocurrent's log).
    """

    def __init__(self, shape: Sequence[int], params: EventParams, *, surround_length_px: float = 2.0,
                 surround_tau_s: float = 1e-3, rng: np.random.Generator, cold_start: bool = False,
                 temperature_k: float = REFERENCE_TEMPERATURE_K):
        real(surround_length_px, "surround_length_px", low=0.0, low_open=True, high=MAX_SURROUND_LENGTH_PX)
        real(surround_tau_s, "surround_tau_s", low=0.0)
        self.dvs = BrightnessEmulator(shape, params, rng=rng, cold_start=cold_start, temperature_k=temperature_k,
                                      light_leak=False)
        self.shape = self.dvs.shape
        self.surround_tau_s = float(surround_tau_s)
        self.c = float(surround_length_px) * float(surround_length_px)
        self._x = thomas_coefficients(self.shape[1], self.c)
        self._y = thomas_coefficients(self.shape[0], self.c)
        self.surround: np.ndarray | None = None

    dtype = BrightnessEmulator.dtype

    def spatial_surround(self, image: np.ndarray) -> np.ndarray:
        """The diffused (H, W) image (steady state of the grid)."""
        out = np.empty(self.shape)
        diffuse(np.ascontiguousarray(image, dtype=np.float64), out, *self._x, *self._y, self.c)
        return out

    def process(self, signal: ArrayLike, t_s: ArrayLike) -> np.ndarray:
        """Events from centre minus surround for samples ``signal`` (T, H, W) at ``t_s`` (T,)."""
        v, t_start, t_end, first = self.dvs.clock.steps(signal, t_s, name="signal")
        if len(t_end) == 0:
            return self.dvs.process(v, t_end)
        tau = self.surround_tau_s
        decay = pm.exp(-(t_end - t_start) / tau) if tau > 0 else np.zeros(len(t_end))
        if first:  # the surround starts settled on the first sample
            decay[0] = 0.0
        surround = np.zeros(self.shape) if first or self.surround is None else self.surround.copy()
        diff = np.empty(v.shape)
        centre_minus_surround(v, decay, surround, *self._x, *self._y, self.c, diff)
        events = self.dvs.process(diff, t_end)
        self.surround = surround
        return events
