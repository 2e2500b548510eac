"""Mixing light-group basis images with lamp waveforms.

Light transport is linear in emitter radiance, so the irradiance at time ``t``
is ``E(t) = sum_k w_k(t) B_k(pose(t))`` over light groups ``k`` (DESIGN.md,
the pipeline), where ``B_k(pose(t))`` blends linearly between the two rendered
poses around ``t``. :func:`mix_poses` is that formula, the one place it is
written: the renderer's radiance and the driver's photocurrent both call it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from gevsim._validate import real_array

from .base import Waveform

__all__ = ["mix", "mix_poses", "weights_at"]


def mix(basis: Any, weights: Any) -> np.ndarray:
    """Weighted sum of basis images, ``sum_k weights[..., k] * basis[k]``.

    Parameters
    ----------
    basis : array, shape (K, H, W) or (K, H, W, C)
        One image per light group (e.g. irradiance at unit waveform).
    weights : array, shape (K,) or (T, K)
        Waveform values per light group, optionally per time step.

    Returns
    -------
    ndarray, shape (H, W[, C]) or (T, H, W[, C])
        float32 if ``basis`` is float32 (halves memory), else float64. Sums accumulate in
        float64 in light-group order (:func:`gevsim._portable.weighted_sum`, not BLAS: the same
        bits on every CPU).
    """
    b = np.asarray(basis)
    if b.ndim not in (3, 4):
        raise ValueError(f"basis must have shape (K, H, W) or (K, H, W, C), got {b.shape}")
    dtype = np.float32 if b.dtype == np.float32 else np.float64
    b = b.astype(dtype, copy=False)
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim not in (1, 2):
        raise ValueError(f"weights must have shape (K,) or (T, K), got {w.shape}")
    if w.shape[-1] != b.shape[0]:
        raise ValueError(f"weights have {w.shape[-1]} light groups (shape {w.shape}) "
                         f"but basis has {b.shape[0]} (shape {b.shape})")
    real_array(w, "weights")
    from gevsim._portable import weighted_sum  # numba: imported where the mixing starts

    out = weighted_sum(w.reshape(-1, w.shape[-1]), b.reshape(b.shape[0], -1), dtype=dtype)
    return out.reshape(w.shape[:-1] + b.shape[1:])


def mix_poses(basis: Any, basis_times_s: Any, t_s: Any, weights: Any) -> np.ndarray:
    """``E(t) = sum_k w_k(t) B_k(pose(t))`` at times ``t_s``, blending the poses around each time.

    Between poses ``i`` and ``i + 1``, ``E = (1 - a) w.B_i + a w.B_{i+1}`` with
    ``a = (t - t_i) / (t_{i+1} - t_i)``; before the first pose and after the last the end
    pose holds. Times are grouped by pose interval, so each group is two matrix products.

    Parameters
    ----------
    basis : array, shape (P, K, H, W) or (P, K, H, W, C)
        One image per pose and light group.
    basis_times_s : array, shape (P,)
        Pose times, increasing.
    t_s : array, shape (T,)
        Times of the result.
    weights : array, shape (T, K)
        Waveform values (or averages) per time and light group (:func:`weights_at`).

    Returns
    -------
    ndarray, shape (T, H, W[, C])
        float32 if ``basis`` is float32, else float64.
    """
    b = np.asarray(basis)
    times = np.asarray(basis_times_s, dtype=np.float64)
    if b.ndim not in (4, 5):
        raise ValueError(f"basis must have shape (P, K, H, W) or (P, K, H, W, C), got {b.shape}")
    if times.shape != b.shape[:1]:
        raise ValueError(f"basis_times_s must have shape ({b.shape[0]},) to match the basis, got {times.shape}")
    if len(times) == 1:
        return mix(b[0], weights)
    dtype = np.float32 if b.dtype == np.float32 else np.float64
    w = np.asarray(weights, dtype=np.float64)
    t = np.asarray(t_s, dtype=np.float64)
    k, shape = b.shape[1], b.shape[2:]
    if w.shape != (len(t), k):
        raise ValueError(f"weights must have shape ({len(t)}, {k}) for {len(t)} times and {k} light groups, "
                         f"got {w.shape}")
    i = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2)
    a = np.clip((t - times[i]) / (times[i + 1] - times[i]), 0.0, 1.0)
    out = np.empty((len(t),) + shape, dtype)
    from gevsim._portable import weighted_sum

    for seg in np.unique(i):
        rows = np.flatnonzero(i == seg)
        wr = w[rows]
        both = np.concatenate([(1.0 - a[rows])[:, None] * wr, a[rows][:, None] * wr], axis=1)  # (rows, 2K)
        pair = np.concatenate([b[seg].reshape(k, -1), b[seg + 1].reshape(k, -1)])  # (2K, N)
        out[rows] = weighted_sum(both, pair, dtype=dtype).reshape((len(rows),) + shape)
    return out


def weights_at(waveforms: Sequence[Waveform], t_s: Any, *, average_over_s: Any = None) -> np.ndarray:
    """Waveform values per time and light group, shape (T, K).

    Parameters
    ----------
    waveforms : sequence of Waveform
        One per light group (K of them).
    t_s : float or 1-D array, shape (T,)
        Times in seconds.
    average_over_s : float or array of shape (T,), optional
        If given (> 0), return the exact mean of each waveform over
        ``[t_s, t_s + average_over_s)`` instead of its value at ``t_s``.
    """
    waveforms = list(waveforms)
    for k, wf in enumerate(waveforms):
        if not isinstance(wf, Waveform):
            raise TypeError(f"waveforms[{k}]={wf!r} is not a Waveform")
    t = np.asarray(t_s, dtype=np.float64)
    if t.ndim > 1:
        raise ValueError(f"t_s must be a scalar or 1-D, got shape {t.shape}")
    t = np.atleast_1d(t)
    real_array(t, "t_s")
    if average_over_s is None:
        cols = [wf(t) for wf in waveforms]
    else:
        d = np.asarray(average_over_s, dtype=np.float64)
        if d.ndim > 1 or (d.ndim == 1 and d.shape != t.shape):
            raise ValueError(f"average_over_s must be a scalar or shape {t.shape}, got shape {d.shape}")
        real_array(d, "average_over_s")
        if np.any(d <= 0):
            raise ValueError(f"average_over_s must be > 0, got {average_over_s!r}")
        end = t + d
        cols = [wf.average(t, end) for wf in waveforms]
    if not cols:
        return np.zeros((t.size, 0))
    return np.stack(cols, axis=-1)
