"""Poisson solvers for Laplacian(R) = c * L_hat on a Neumann (reflecting) grid.

The discrete Laplacian is the paper's 5-point kernel D^2_xy applied with
reflecting boundaries (a missing neighbour equals the cell itself), which is
what A_X + A_Y of Lehtonen et al., Sec. "Computing an approximation of the
discrete Laplacian", computes from G_X, G_Y with zero last column/row.

Solvers (``method=``):

``"sor"``
    Red-black successive over-relaxation as in the paper (Sec. "Solving the
    Poisson's equation with successive over-relaxation"; alpha = 1.97,
    k = 100, R initialised to 0 or warm-started from ``initial``).
``"dct"``
    The exact solution of the same discrete problem: the Neumann 5-point
    Laplacian is diagonalised by the DCT-II, with eigenvalues
    (2 cos(pi u / W) - 2) + (2 cos(pi v / H) - 2); the zero-frequency mode
    (the unknown mean) is set to 0. O(N log N), no iteration count. Computed
    as a 1-D DCT plus cached tridiagonal solves (:mod:`._tridiagonal`).

Both return R zero-centred. The Neumann problem has a solution only if
sum(L_hat) = 0; this holds for the paper's L_hat without resolution
compression. With RC the last pair duplicates G_X^RC(W-2) = G_X(W-2) / 2 into
column W-1 (and likewise the last row), so sum(L_hat) != 0. The DCT then
returns the least-squares solution (L_hat minus its mean); SOR, run on L_hat as
the paper does, drifts by a constant (removed by zero-centring) and converges
to a slightly different solution (camera at 80x60: 2 % of the range).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.fft

from gevsim import _portable as pm
from gevsim.errors import suggest
from gevsim.reconstruct import _tridiagonal
from gevsim.reconstruct._sor import sor_numba

#: Paper's SOR parameters (Lehtonen et al., Sec. "Reconstruction example").
PAPER_ALPHA = 1.97
PAPER_ITERATIONS = 100
#: Workers for scipy.fft (this project's reference machine has 2 cores); used from
#: PARALLEL_PIXELS pixels on (threads cost more than they save on small frames, measured).
FFT_WORKERS = 2
PARALLEL_PIXELS = 2**18


def _check_field(lhat, name="L_hat") -> np.ndarray:
    a = np.asarray(lhat)
    if a.ndim != 2 or min(a.shape) < 1:
        raise ValueError(f"{name} must be a 2-D (H, W) array, got shape {a.shape}")
    if not np.issubdtype(a.dtype, np.number) or np.iscomplexobj(a):
        raise TypeError(f"{name} must be a real numeric array, got dtype {a.dtype}")
    return a


def laplacian(image: np.ndarray) -> np.ndarray:
    """5-point discrete Laplacian (the paper's D^2_xy) with reflecting (Neumann) boundaries."""
    img = _check_field(image, "image").astype(np.float64)
    p = np.pad(img, 1, mode="edge")
    return p[:-2, 1:-1] + p[2:, 1:-1] + p[1:-1, :-2] + p[1:-1, 2:] - 4.0 * img


def sor(lhat: np.ndarray, *, c: float = 1.0, alpha: float = PAPER_ALPHA,
        iterations: int = PAPER_ITERATIONS, initial: np.ndarray | None = None) -> np.ndarray:
    """Solve Laplacian(R) = c * L_hat by ``iterations`` red-black SOR sweeps.

    Parameters
    ----------
    lhat : (H, W) approximate Laplacian L_hat (paper Eq. for L_hat).
    c : scaling constant (paper: 3.6 with three thresholds, 4.3 with one).
    alpha : over-relaxation parameter in (0, 2) (paper: 1.97).
    iterations : number k of red-black iterations (paper: 100).
    initial : start value of R (warm start, e.g. the previous frame); zeros when None.

    Returns
    -------
    R, float64 (H, W), zero-centred.
    """
    b = c * _check_field(lhat).astype(np.float64)
    if not 0.0 < alpha < 2.0:
        raise ValueError(f"alpha must lie in (0, 2) for SOR to converge, got {alpha!r}")
    if int(iterations) != iterations or iterations < 0:
        raise ValueError(f"iterations must be a non-negative integer, got {iterations!r}")
    if initial is None:
        r = np.zeros_like(b)
    else:
        r = np.array(initial, dtype=np.float64, order="C", copy=True)
        if r.shape != b.shape:
            raise ValueError(f"initial must have the shape of L_hat {b.shape}, got {r.shape}")
    sor_numba(r, np.ascontiguousarray(b), float(alpha), int(iterations))
    r -= r.mean()
    return r


@functools.lru_cache(maxsize=64)
def _inverse_eigenvalues(n: int, dtype: str) -> np.ndarray:
    """1 / eigenvalues 2 cos(pi k / n) - 2 of the 1-D Neumann second difference; 0 at k = 0."""
    lam = 2.0 * pm.cos(np.pi * np.arange(n) / n) - 2.0
    lam[0] = 1.0
    inv = 1.0 / lam
    inv[0] = 0.0  # the mean is unknown: zero-frequency mode set to 0
    inv = inv.astype(dtype)
    inv.flags.writeable = False
    return inv


@functools.lru_cache(maxsize=64)
def _largest_prime_factor(n: int) -> int:
    """FFT cost grows with the largest prime factor of the length (346 = 2 x 173 is slow)."""
    largest, p = 1, 2
    while p * p <= n:
        while n % p == 0:
            largest, n = p, n // p
        p += 1
    return max(largest, n)


def dct(lhat: np.ndarray, *, c: float = 1.0) -> np.ndarray:
    """Exact Neumann solution of Laplacian(R) = c * L_hat by DCT-II (zero-centred).

    Mathematically R = IDCT2(c DCT2(L_hat) / (lam_v + lam_u)) with the zero-frequency mode 0.
    It is computed as a 1-D DCT-II (scipy.fft.dct, norm="ortho") along one axis, a cached
    tridiagonal (Thomas) solve per frequency along the other axis and the inverse DCT: the same
    exact answer, and much faster when one side has a large prime factor (346 = 2 x 173). The
    transform runs along the axis with the smaller largest prime factor. Agrees with the 2-D DCT to ~1e-13.
    float32 input is solved in float32 (~1e-4 relative at 1280x720); anything else in float64.
    """
    a = _check_field(lhat)
    dtype = np.float32 if a.dtype == np.float32 else np.float64
    a = a.astype(dtype, copy=False)
    transpose = _largest_prime_factor(a.shape[0]) < _largest_prime_factor(a.shape[1])
    if transpose:  # transform along the fast side, kept contiguous as axis 1
        a = a.T
    workers = FFT_WORKERS if a.size >= PARALLEL_PIXELS else 1
    f = scipy.fft.dct(a, type=2, norm="ortho", axis=1, workers=workers)  # a copy
    f = np.ascontiguousarray(f)
    _tridiagonal.solve_columns(f, _tridiagonal.factor(f.shape, np.dtype(dtype).name), dtype(c))
    # Column u = 0 is the singular pure-Neumann 1-D problem: solve it by its own DCT.
    g = scipy.fft.dct(f[:, 0], type=2, norm="ortho") * _inverse_eigenvalues(f.shape[0], np.dtype(dtype).name)
    f[:, 0] = scipy.fft.idct(g * dtype(c), type=2, norm="ortho")
    r = scipy.fft.idct(f, type=2, norm="ortho", axis=1, workers=workers, overwrite_x=True)
    return r.T.copy() if transpose else r


def _dct2(lhat: np.ndarray, *, c: float = 1.0) -> np.ndarray:
    """Reference: the same solution by a 2-D DCT-II (used by the tests and the benchmark)."""
    a = _check_field(lhat).astype(np.float64)
    f = scipy.fft.dctn(a, type=2, norm="ortho", workers=FFT_WORKERS)
    f *= c * (_inverse_2d(a.shape))
    return scipy.fft.idctn(f, type=2, norm="ortho", workers=FFT_WORKERS, overwrite_x=True)


@functools.lru_cache(maxsize=32)
def _inverse_2d(shape: tuple[int, int]) -> np.ndarray:
    h, w = shape
    lam = (2.0 * pm.cos(np.pi * np.arange(h) / h) - 2.0)[:, None] + (2.0 * pm.cos(np.pi * np.arange(w) / w) - 2.0)
    lam[0, 0] = 1.0
    inv = 1.0 / lam
    inv[0, 0] = 0.0
    inv.flags.writeable = False
    return inv


SOLVERS = {"sor": sor, "dct": dct}


def check_method(method: str) -> Callable[..., np.ndarray]:
    """The solver ``SOLVERS[method]``; ValueError with a did-you-mean for an unknown name."""
    try:
        return SOLVERS[method]
    except (KeyError, TypeError):
        raise ValueError(f"unknown Poisson solver method {method!r}{suggest(str(method), SOLVERS)}; "
                         f"choose from {', '.join(sorted(SOLVERS))}") from None


def solve_poisson(lhat: np.ndarray, *, method: str = "dct", **kw: Any) -> np.ndarray:
    """Solve Laplacian(R) = c * L_hat with the solver ``SOLVERS[method]``; R zero-centred.

    Keyword arguments go to the solver: ``c`` for both; ``alpha``, ``iterations``,
    ``initial`` for ``"sor"``.
    """
    return check_method(method)(lhat, **kw)
