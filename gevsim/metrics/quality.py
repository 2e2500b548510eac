"""Full-reference image quality, computed as EVREAL computes it.

EVREAL (Ercan et al., CVPRW 2023; github.com/ercanburak/EVREAL,
``utils/eval_metrics.py`` and ``eval.py``):

- prediction and reference are clipped to [0, 1] (``np.clip``) before scoring;
- MSE = ``skimage.metrics.mean_squared_error(ref, img)``;
- SSIM = ``skimage.metrics.structural_similarity(ref, img, gaussian_weights=True,
  sigma=1.5, use_sample_covariance=False, data_range=1.0)``;
- LPIPS through pyiqa (AlexNet, v0.1 linear layers);
- a reconstruction is scored against a reference frame only when their
  timestamps differ by at most ``ts_tol_ms`` (1 ms in ``config/eval/std.json``);
- a sequence score is the mean of its frame scores, non-finite scores dropped
  (``BaseMetric.update`` keeps only finite values);
- a dataset score is the mean of sequence scores weighted by the number of
  evaluated frames (``MetricTracker.update(key, score, num_evaluated)``).

EVREAL reports no PSNR; here PSNR = 10 log10(1 / MSE) on the same clipped
frames (data range 1), infinite for identical frames. Frames are grayscale
(H, W); EVREAL skips quantitative scoring of colour output. Arithmetic is
float64 (EVREAL scores float32 network output).
"""

from __future__ import annotations

import importlib.util
import math
import os
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from skimage.metrics import mean_squared_error, structural_similarity

from gevsim import _portable as pm
from gevsim._validate import real, real_array

SSIM_KWARGS = dict(gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=1.0)
"""EVREAL's SsimMetric arguments."""
TS_TOL_US = 1000
"""EVREAL's default timestamp tolerance (``ts_tol_ms`` = 1.0 in config/eval/std.json)."""
_SSIM_MIN_SIDE = 11  # Gaussian window of sigma 1.5: 2 * int(3.5 * 1.5 + 0.5) + 1


def _pair(pred, gt):
    pred, gt = np.asarray(pred), np.asarray(gt)
    if pred.ndim != 2 or gt.shape != pred.shape:
        raise ValueError(f"pred and gt must be 2-D grayscale frames of equal shape, got {pred.shape} and {gt.shape}")
    for name, a in (("pred", pred), ("gt", gt)):
        real_array(a, name)
    return np.clip(pred.astype(np.float64), 0.0, 1.0), np.clip(gt.astype(np.float64), 0.0, 1.0)


def mse(pred: ArrayLike, gt: ArrayLike) -> float:
    """Mean squared error of the [0, 1]-clipped frames (EVREAL's MseMetric)."""
    p, g = _pair(pred, gt)
    return float(mean_squared_error(g, p))


def ssim(pred: ArrayLike, gt: ArrayLike) -> float:
    """SSIM of the [0, 1]-clipped frames with EVREAL's arguments (:data:`SSIM_KWARGS`)."""
    p, g = _pair(pred, gt)
    if min(p.shape) < _SSIM_MIN_SIDE:
        raise ValueError(f"SSIM needs frames of at least {_SSIM_MIN_SIDE}x{_SSIM_MIN_SIDE} px, got {p.shape}")
    return float(structural_similarity(g, p, **SSIM_KWARGS))


def psnr(pred: ArrayLike, gt: ArrayLike) -> float:
    """10 log10(1 / MSE) in dB on the [0, 1]-clipped frames; ``inf`` when they are equal."""
    e = mse(pred, gt)
    return math.inf if e == 0.0 else 10.0 * float(pm.log10(1.0 / e))


def lpips_unavailable_reason() -> str | None:
    """Why LPIPS (AlexNet, v0.1) cannot be computed here, or None when it can."""
    for module in ("torch", "lpips"):
        if importlib.util.find_spec(module) is None:
            return f"LPIPS unavailable: the {module!r} package is not installed"
    import torch  # noqa: PLC0415  (optional dependency)

    ckpt = os.path.join(torch.hub.get_dir(), "checkpoints")
    try:
        found = any(name.startswith("alexnet-") for name in os.listdir(ckpt))
    except OSError:
        found = False
    if not found:
        return f"LPIPS unavailable: AlexNet weights not found under {ckpt} (no download is attempted)"
    return None


def lpips_available() -> bool:
    """True when the ``lpips`` package and its AlexNet weights are present locally."""
    return lpips_unavailable_reason() is None


_LPIPS_NET = None


def lpips(pred: ArrayLike, gt: ArrayLike) -> float | None:
    """LPIPS (AlexNet, v0.1) of the clipped frames, or None when unavailable (see :func:`lpips_unavailable_reason`)."""
    p, g = _pair(pred, gt)
    if not lpips_available():
        return None
    global _LPIPS_NET
    import lpips as _lp  # noqa: PLC0415
    import torch  # noqa: PLC0415

    if _LPIPS_NET is None:
        _LPIPS_NET = _lp.LPIPS(net="alex", version="0.1", verbose=False).eval()

    def tensor(a):  # gray [0, 1] -> 1x3xHxW in [-1, 1], as pyiqa feeds LPIPS
        return torch.from_numpy(a).float()[None, None].repeat(1, 3, 1, 1) * 2.0 - 1.0

    with torch.no_grad():
        return float(_LPIPS_NET(tensor(p), tensor(g)).item())


def frame_metrics(pred: ArrayLike, gt: ArrayLike) -> dict:
    """``{"mse", "ssim", "psnr", "lpips"}`` for one frame pair; ``lpips`` is None when unavailable,
    with the reason under ``"unavailable"`` (a dict metric name -> reason)."""
    out: dict[str, Any] = {"mse": mse(pred, gt), "ssim": ssim(pred, gt), "psnr": psnr(pred, gt),
                           "lpips": lpips(pred, gt)}
    reason = lpips_unavailable_reason()
    out["unavailable"] = {} if reason is None else {"lpips": reason}
    return out


def pair_by_timestamp(pred_t_us: ArrayLike, gt_t_us: ArrayLike, *,
                      tolerance_us: float = TS_TOL_US) -> tuple[np.ndarray, np.ndarray]:
    """Match each reconstruction to the ground-truth frame nearest in time.

    Returns ``(pred_idx, gt_idx)`` int arrays. A reconstruction whose nearest
    ground-truth timestamp is more than ``tolerance_us`` away is dropped; on a
    tie the earlier ground-truth frame wins. ``gt_t_us`` must be non-decreasing.
    """
    pt, gt_t = np.asarray(pred_t_us, dtype=np.float64), np.asarray(gt_t_us, dtype=np.float64)
    if pt.ndim != 1 or gt_t.ndim != 1:
        raise ValueError(f"timestamps must be 1-D, got shapes {pt.shape} and {gt_t.shape}")
    real_array(pt, "pred_t_us")
    real_array(gt_t, "gt_t_us")
    real(tolerance_us, "tolerance_us", low=0.0)
    if gt_t.size > 1 and np.any(np.diff(gt_t) < 0):
        raise ValueError("gt_t_us must be non-decreasing")
    if gt_t.size == 0 or pt.size == 0:
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)
    right = np.clip(np.searchsorted(gt_t, pt, side="left"), 0, gt_t.size - 1)
    left = np.clip(right - 1, 0, gt_t.size - 1)
    use_left = np.abs(pt - gt_t[left]) <= np.abs(gt_t[right] - pt)
    nearest = np.where(use_left, left, right)
    keep = np.abs(gt_t[nearest] - pt) <= tolerance_us
    return np.flatnonzero(keep), nearest[keep]


def sequence_metrics(preds: ArrayLike, pred_t: ArrayLike, gts: ArrayLike, gt_t: ArrayLike, *,
                     tolerance_us: float = TS_TOL_US) -> dict:
    """Per-sequence mean of :func:`frame_metrics` over timestamp-paired frames.

    Non-finite frame scores (PSNR of identical frames) are left out of the
    mean, as EVREAL does. The result holds ``n_frames`` (pairs scored) and
    ``unavailable`` (metric -> reason). Raises ValueError when no frame pairs.
    """
    preds, gts, pred_t, gt_t = np.asarray(preds), np.asarray(gts), np.asarray(pred_t), np.asarray(gt_t)
    if preds.ndim != 3 or gts.ndim != 3:
        raise ValueError(f"preds and gts must be (N, H, W) stacks, got {preds.shape} and {gts.shape}")
    if len(pred_t) != preds.shape[0] or len(gt_t) != gts.shape[0]:
        raise ValueError(
            f"timestamp counts ({len(pred_t)}, {len(gt_t)}) must match frame counts ({preds.shape[0]}, {gts.shape[0]})"
        )
    pi, gi = pair_by_timestamp(pred_t, gt_t, tolerance_us=tolerance_us)
    if pi.size == 0:
        raise ValueError(f"no ground-truth frame within {tolerance_us} us of any reconstruction: nothing to score")
    per = [frame_metrics(preds[i], gts[j]) for i, j in zip(pi, gi)]
    out: dict[str, Any] = {}
    for key in ("mse", "ssim", "psnr", "lpips"):
        vals = [f[key] for f in per]
        if any(v is None for v in vals):
            out[key] = None
            continue
        finite = [v for v in vals if math.isfinite(v)]
        out[key] = float(np.mean(finite)) if finite else math.nan
    out["n_frames"] = int(pi.size)
    out["unavailable"] = dict(per[0]["unavailable"])
    return out


def aggregate(results: Sequence[dict]) -> dict:
    """Frame-count-weighted mean over sequences: ``results`` is a list of (metrics dict, n_frames).

    Sequences with zero frames are skipped (EVREAL's MetricTracker). A metric
    that is None in any sequence is None in the aggregate, with its reason kept.
    """
    results = list(results)
    keys = None
    total = 0
    sums: dict = {}
    unavailable: dict = {}
    for metrics, n in results:
        if not isinstance(n, (int, np.integer)) or n < 0:
            raise ValueError(f"n_frames must be a non-negative integer, got {n!r}")
        if n == 0:
            continue
        these = set(metrics) - {"n_frames", "unavailable"}
        if keys is not None and these != keys:
            raise ValueError(f"sequences report different metrics: {sorted(keys)} vs {sorted(these)}")
        keys = these
        total += int(n)
        unavailable.update(metrics.get("unavailable", {}))
        for key, value in metrics.items():
            if key in ("n_frames", "unavailable"):
                continue
            if value is None or sums.get(key, 0.0) is None:
                sums[key] = None
            else:
                sums[key] = sums.get(key, 0.0) + float(value) * int(n)
    if total == 0:
        raise ValueError("aggregate needs at least one sequence with frames")
    out = {key: (None if s is None else s / total) for key, s in sums.items()}
    out["n_frames"] = total
    out["unavailable"] = unavailable
    return out
