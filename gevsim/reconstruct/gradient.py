"""Frame reconstruction from ternary gradients / gradient events (Poisson).

Lehtonen et al., Sec. "Reconstruction of grayscale images": the quantized
gradients G_hat = T o Theta (Eqs. for G_hat_X, G_hat_Y) give the approximate
discrete Laplacian

    A_hat_X(x, y) = G_hat_X(x, y) - G_hat_X(x-1, y),  A_hat_X(0, y) = G_hat_X(0, y),
    A_hat_Y(x, y) = G_hat_Y(x, y) - G_hat_Y(x, y-1),  A_hat_Y(x, 0) = G_hat_Y(x, 0),
    L_hat = A_hat_X + A_hat_Y                                  (Eq. approximate_discrete_laplacian)

and R solves Laplacian(R) = c * L_hat (c = 3.6 for the thresholds {4, 8, 16}/255,
4.3 for the single threshold 4/255, Fig. "three vs one thresholds"); R is
zero-centred and a mean is added (the paper adds the ground-truth mean).
The solvers (``method=``: ``"sor"``, ``"dct"``) live in :mod:`gevsim.reconstruct.poisson`.
"""

from __future__ import annotations

import numpy as np

from gevsim import _portable as pm
from gevsim.events.types import AXIS_X, AXIS_Y
from gevsim.reconstruct.poisson import (  # noqa: F401  (re-exported)
    PAPER_ALPHA,
    PAPER_ITERATIONS,
    SOLVERS,
    check_method,
    dct,
    laplacian,
    solve_poisson,
    sor,
)

#: Scaling constant c of the paper for three thresholds {4, 8, 16}/255 (Sec. "Reconstruction example").
PAPER_C = 3.6
#: Scaling constant c of the paper for the single threshold 4/255 (Fig. three_vs_one_thresholds).
PAPER_C_SINGLE = 4.3


def _check_state(ternary_state) -> np.ndarray:
    t = np.asarray(ternary_state)
    if t.ndim != 3 or t.shape[0] != 2:
        raise ValueError(f"ternary_state must have shape (2, H, W) (axis 0: X, Y), got {t.shape}")
    return t


def _theta2(theta, shape) -> np.ndarray:
    th = np.asarray(theta, dtype=np.float64)
    if th.shape == shape:
        return np.broadcast_to(th, (2,) + shape)
    if th.shape == (2,) + shape:
        return th
    raise ValueError(f"theta must have shape {shape} or {(2,) + shape}, got {th.shape}")


def quantized_gradients(ternary_state: np.ndarray, theta: np.ndarray, *,
                        rc: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """G_hat_X, G_hat_Y = T o Theta from a (2, H, W) ternary state.

    Parameters
    ----------
    ternary_state : (2, H, W) ternary gradients T in {-1, 0, 1}; axis 0 is X, 1 is Y.
    theta : threshold matrix, (H, W) shared by both axes or (2, H, W) per axis.
    rc : resolution compression: the comparator of each pair sits at the even x (X axis) or
        even y (Y axis); its value is copied to the odd member, as in the paper's Eqs. for
        G^RC (G^RC(x+1, y) = G^RC(x, y)). Odd positions of ``ternary_state`` are ignored.
    """
    t = _check_state(ternary_state)
    shape = t.shape[1:]
    if rc and (shape[0] % 2 or shape[1] % 2):
        raise ValueError(f"resolution compression needs even height and width, got {shape[0]}x{shape[1]}")
    th = _theta2(theta, shape)
    gx = t[AXIS_X].astype(np.float64) * th[AXIS_X]
    gy = t[AXIS_Y].astype(np.float64) * th[AXIS_Y]
    if rc:
        gx[:, 1::2] = gx[:, 0::2]
        gy[1::2, :] = gy[0::2, :]
    return gx, gy


def approximate_laplacian(ghat_x: np.ndarray, ghat_y: np.ndarray) -> np.ndarray:
    """L_hat = A_hat_X + A_hat_Y (paper Eq. approximate_discrete_laplacian and the A_hat Eqs.).

    With exact gradients (last column of G_X and last row of G_Y zero) this is the 5-point
    Laplacian with reflecting boundaries (:func:`gevsim.reconstruct.poisson.laplacian`).
    """
    gx = np.asarray(ghat_x, dtype=np.float64)
    gy = np.asarray(ghat_y, dtype=np.float64)
    if gx.ndim != 2 or gx.shape != gy.shape:
        raise ValueError(f"ghat_x and ghat_y must be 2-D arrays of one shape, got {gx.shape} and {gy.shape}")
    a_x = gx.copy()
    a_x[:, 1:] -= gx[:, :-1]  # A_X(0, y) = G_X(0, y)
    a_y = gy.copy()
    a_y[1:, :] -= gy[:-1, :]  # A_Y(x, 0) = G_Y(x, 0)
    return a_x + a_y


def global_photodiode_mean(log_image: np.ndarray) -> float:
    """The level one extra global photodiode would give: ln of the mean irradiance.

    Gradient events carry no mean intensity; the paper adds the ground-truth mean and
    suggests a global illumination sensor instead (Sec. "Reconstruction example"). A
    photodiode spanning the array measures the total photocurrent, i.e. the mean of
    exp(log_image), so its log is ``logsumexp(log_image) - ln N`` (>= the mean of the log).
    With it, reconstruction needs no ground-truth frame.
    """
    a = np.asarray(log_image, dtype=np.float64)
    if a.ndim != 2:
        raise ValueError(f"log_image must be a 2-D (H, W) array, got shape {a.shape}")
    peak = float(a.max())  # log-sum-exp, shifted so that no exp overflows
    return peak + float(pm.log(float(np.sum(pm.exp(a - peak))))) - float(pm.log(float(a.size)))


def _solver_options(method, c, initial, alpha, iterations) -> dict:
    if method == "sor":
        return dict(c=c, alpha=alpha, iterations=iterations, initial=initial)
    return dict(c=c)


def reconstruct(ternary_state: np.ndarray, theta: np.ndarray, *, rc: bool = False, method: str = "dct",
                c: float = PAPER_C, mean: float = 0.0, initial: np.ndarray | None = None,
                alpha: float = PAPER_ALPHA, iterations: int = PAPER_ITERATIONS) -> np.ndarray:
    """Reconstructed frame R + mean from ternary gradients (paper Sec. "Reconstruction").

    Parameters
    ----------
    ternary_state, theta, rc : as :func:`quantized_gradients`.
    method : Poisson solver, a key of :data:`SOLVERS` (``"dct"`` exact, ``"sor"`` the paper's).
    c : scaling constant of L_hat (paper: 3.6; 4.3 for one threshold).
    mean : bias added to the zero-centred R (ground-truth mean in the paper, or
        :func:`global_photodiode_mean`).
    initial, alpha, iterations : SOR only: warm start (zero-centred R of the previous frame),
        over-relaxation parameter (1.97) and iteration count k (100).
    """
    check_method(method)
    lhat = approximate_laplacian(*quantized_gradients(ternary_state, theta, rc=rc))
    r = solve_poisson(lhat, method=method, **_solver_options(method, c, initial, alpha, iterations))
    return r + mean


class GradientReconstructor:
    """Streaming reconstruction from successive ternary states (e.g. decoded gradient events).

    With ``method="sor"`` and ``warm_start`` each frame's SOR starts from the previous
    zero-centred R, the paper's real-time setting (Sec. "Solving the Poisson's equation").

    Parameters
    ----------
    shape : (H, W).
    theta : (H, W) or (2, H, W) threshold matrix (e.g. ``GradientEmulator.theta``).
    rc, method, c : as :func:`reconstruct`.
    warm_start : SOR from the previous frame (True) or from zero every frame.
    alpha, iterations : SOR parameters.
    """

    def __init__(self, shape: tuple[int, int], theta: np.ndarray, *, rc: bool = False, method: str = "dct",
                 c: float = PAPER_C, warm_start: bool = True, alpha: float = PAPER_ALPHA,
                 iterations: int = PAPER_ITERATIONS):
        self.shape = tuple(int(n) for n in shape)
        if len(self.shape) != 2:
            raise ValueError(f"shape must be (H, W), got {shape!r}")
        self.theta = _theta2(theta, self.shape).copy()
        check_method(method)
        self.rc, self.method, self.c = bool(rc), method, float(c)
        self.warm_start, self.alpha, self.iterations = bool(warm_start), float(alpha), int(iterations)
        self.previous: np.ndarray | None = None  # zero-centred R of the last frame

    def frame(self, state: np.ndarray, *, mean: float = 0.0) -> np.ndarray:
        """Reconstruct one frame from the (2, H, W) ternary ``state``; returns R + ``mean``."""
        t = _check_state(state)
        if t.shape[1:] != self.shape:
            raise ValueError(f"state must have shape {(2,) + self.shape}, got {t.shape}")
        initial = self.previous if self.warm_start else None
        r = reconstruct(t, self.theta, rc=self.rc, method=self.method, c=self.c, initial=initial,
                        alpha=self.alpha, iterations=self.iterations)
        self.previous = r
        return r + mean

    def reset(self) -> None:
        """Forget the previous frame (next SOR starts from zero)."""
        self.previous = None
