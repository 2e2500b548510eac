"""Render to a noise target: batch statistics of ln(radiance) and the stop rule.

A pose is rendered in independent batches (different sampler seeds). Each
batch gives K light-group images ``G[k]`` from ``n_b`` samples per pixel; the
batch means are independent and identically distributed up to their sample
count, whatever the sampler's stratification inside a batch, so their spread
is an honest estimate of the Monte Carlo error (Owen, *Monte Carlo theory,
methods and examples*, 2013, ch. 2 and 17, batch means).

For each lamp mixture ``w`` the waveforms reach (the corners of the box
``[min_k, max_k]`` of the groups' waveform ranges) the pixel luminance is
``Y(w) = sum_k w_k Y_k``. With ``N = sum n_b`` and the weighted batch mean
``Ybar``, the per-sample variance is estimated as
``s^2 = (sum_b n_b Y_b^2 - N Ybar^2) / (B - 1)`` and the standard error of
``ln Ybar`` by the delta method as ``sqrt(s^2 / N) / (Ybar + floor)``. The
``floor`` (``noise_floor_rel`` times the mixture's image mean) keeps pixels
that a mixture leaves black from demanding unbounded samples; the
photoreceptor's dark current plays the same part in the sensor.

By default (``noise_metric = "flicker"``) the error measured is that of the
*change* ``ln Y(w) - ln Y(wbar)`` from the time-mean mixture ``wbar``: render
noise common to every mixture is a static pattern that no lamp turns into
events, and the groups share their paths, so much of it is common. Its
variance follows from the batches' covariance of ``Y(w)`` and ``Y(wbar)``.
``noise_metric = "absolute"`` measures ln Y(w) itself.

The stop rule: the ``percentile``-th percentile over pixels of the largest
standard error over mixtures is at most the target. With B batches the
per-pixel estimate has B - 1 degrees of freedom; its scatter can only raise a
high percentile, so the rule errs on the side of more samples. Manabe et al.
(ICCP 2024) stop per pixel on a test of log luminance for the same reason:
event thresholds are contrasts, so the error that matters is that of ln.

Batches are assigned alternately to two halves of equal sample count; half
the difference of the halves, ``D = (H0 - H1) / 2``, has the variance of the
full estimate's error, which is what the render-noise floor of an emulation
needs (:func:`gevsim.emulation.driver.render_noise_floor`).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from gevsim._validate import integer, real

#: Batches before the first check of the stop rule (7 degrees of freedom).
MIN_BATCHES = 8
#: Batches per growth step: batch size is kept near N / BATCH_SPREAD so B stays >= this.
BATCH_SPREAD = 16


def mixture_weights(ranges: list[tuple[float, float]], *, max_corners: int = 64) -> np.ndarray:
    """(M, K) lamp mixtures to watch: the corners of the waveform-range box.

    ``ranges[k]`` is ``(min, max)`` of group k's waveform. With more than
    ``log2(max_corners)`` flickering groups, only all-minimum, all-maximum and
    each group alone at its extreme are kept.
    """
    if not ranges:
        raise ValueError("mixture_weights: no light groups")
    lo = np.array([float(a) for a, _ in ranges])
    hi = np.array([float(b) for _, b in ranges])
    if np.any(~np.isfinite(lo)) or np.any(~np.isfinite(hi)) or np.any(lo < 0) or np.any(hi < lo):
        raise ValueError(f"mixture_weights: waveform ranges must be finite with 0 <= min <= max, got {ranges}")
    varying = np.flatnonzero(hi > lo)
    if 2 ** len(varying) <= max_corners:
        rows = []
        for corner in itertools.product((0, 1), repeat=len(varying)):
            w = lo.copy()
            w[varying] = np.where(np.array(corner, bool), hi[varying], lo[varying])
            rows.append(w)
    else:
        rows = [lo.copy(), hi.copy()]
        for k in varying:
            for base, extreme in ((lo, hi), (hi, lo)):
                w = base.copy()
                w[k] = extreme[k]
                rows.append(w)
    rows = [w for w in rows if w.sum() > 0] or [hi]
    return np.unique(np.array(rows), axis=0)


@dataclass(frozen=True)
class NoiseReport:
    """What a converged (or stopped) render achieved."""

    spp: int
    batches: int
    se_ln_percentiles: dict  # {"p50": ..., "p90": ..., "p99": ..., "max": ...} of the worst mixture per pixel
    percentile: float
    target_ln: float | None
    stopped_by: str  # "target", "max_spp", "time_budget", "fixed"
    seconds: float
    denoised_se_ln: dict | None = None  # percentiles of the denoised images' error (sample_se_ln), if denoised
    spp_mean: float | None = None  # samples per pixel on average (below ``spp``, the most, under adaptive sampling)

    @property
    def se_ln(self) -> float:
        """The stop statistic: the ``percentile``-th percentile of the standard error of ln."""
        return self.se_ln_percentiles["at_percentile"]

    @property
    def reached(self) -> bool:
        return self.target_ln is None or self.se_ln <= self.target_ln

    def as_dict(self) -> dict:
        return {"spp": self.spp, "batches": self.batches, "percentile": self.percentile,
                "target_ln": self.target_ln, "stopped_by": self.stopped_by, "seconds": self.seconds,
                "se_ln": {k: float(v) for k, v in self.se_ln_percentiles.items()},
                "denoised": self.denoised_se_ln is not None, "denoised_se_ln": self.denoised_se_ln,
                "spp_mean": self.spp if self.spp_mean is None else self.spp_mean}


#: What the stop rule measures: the error of ln Y(w) itself ("absolute"), or of its change
#: ln Y(w) - ln Y(wbar) from the time-mean mixture ("flicker"), the part that lamp flicker turns into events.
METRICS = ("flicker", "absolute")


class BatchAccumulator:
    """Running batch statistics of K group images and the ln error of their mixtures.

    Parameters
    ----------
    mixtures : (M, K) lamp weights (:func:`mixture_weights`).
    floor_rel : the error is taken relative to ``Y + floor_rel * mean(Y)``.
    reference : (K,) the time-mean mixture (every waveform has mean 1, so ones by default).
    metric : ``"flicker"``: the standard error of ln Y(w) - ln Y(reference), by the delta
        method with the batches' covariance. A noise pattern shared by every mixture is
        static and causes no flicker events; only its change with the mixture does.
        ``"absolute"``: the standard error of ln Y(w).
    cells : images come in ``cells`` x ``cells`` cells per pixel (a supersampled render): the
        images, halves and noise stay at cell resolution, the error statistics are of the pixels
        (each the mean of its cells; ``spp`` counts the pixel's samples).
    """

    def __init__(self, mixtures: np.ndarray, *, floor_rel: float = 1e-3, reference: np.ndarray | None = None,
                 metric: str = "flicker", cells: int = 1):
        mixtures = np.asarray(mixtures, float)
        if mixtures.ndim != 2 or mixtures.shape[0] < 1:
            raise ValueError(f"BatchAccumulator: mixtures must be (M, K), got shape {mixtures.shape}")
        real(floor_rel, "floor_rel", low=0.0, low_open=True)
        if metric not in METRICS:
            raise ValueError(f"BatchAccumulator: metric must be one of {METRICS}, got {metric!r}")
        reference = np.ones(mixtures.shape[1]) if reference is None else np.asarray(reference, float)
        if reference.shape != (mixtures.shape[1],):
            raise ValueError(f"BatchAccumulator: reference must have {mixtures.shape[1]} weights, got {reference!r}")
        self.mixtures = np.vstack([mixtures, reference])  # the last row is the reference
        self.cells = integer(cells, "cells", low=1)
        self.metric = metric
        self.floor_rel = float(floor_rel)
        self.spp = 0  # the most samples any pixel has
        self.batches = 0  # the most batches any pixel has
        self._n: np.ndarray | None = None  # per pixel: samples, batches, and samples in each half, (H, W)
        self._nb: np.ndarray | None = None
        self._half_n: np.ndarray | None = None  # (2, H, W)
        self._halves: list[np.ndarray] = []  # sum of n_b * G_b per half, (K, H, W, C) float64
        self._p: np.ndarray | None = None  # sum n_b Y_b, (M + 1, H, W)
        self._q: np.ndarray | None = None  # sum n_b Y_b^2
        self._c: np.ndarray | None = None  # sum n_b Y_b Y_ref,b

    def add(self, images: np.ndarray, luminance: np.ndarray, spp: int, mask: np.ndarray | None = None) -> None:
        """Add a batch: ``images`` (K, H, W, C) radiance, ``luminance`` (K, H, W), from ``spp`` samples.
        ``mask`` (H, W pixels, bool): only these pixels were rendered (per-pixel adaptive sampling); the
        images must be zero elsewhere. None: every pixel."""
        images = np.asarray(images)
        lum = np.asarray(luminance, float)
        k = self.mixtures.shape[1]
        if images.ndim != 4 or images.shape[0] != k or lum.shape != images.shape[:3]:
            raise ValueError(f"BatchAccumulator.add: expected ({k}, H, W, C) images and ({k}, H, W) luminance, "
                             f"got {images.shape} and {lum.shape}")
        integer(spp, "spp", low=1)
        if self.cells > 1:
            c, (kk, h, w) = self.cells, lum.shape
            if h % c or w % c:
                raise ValueError(f"BatchAccumulator.add: {w}x{h} cells are not whole pixels of {c}x{c} cells")
            lum = lum.reshape(kk, h // c, c, w // c, c).mean(axis=(2, 4))
        y = np.tensordot(self.mixtures, lum, axes=1)  # (M + 1, H, W) pixels
        weighted = images.astype(np.float64) * spp
        if self._p is None or self._q is None or self._c is None:
            self._p, self._q, self._c = spp * y, spp * y * y, spp * y * y[-1]
            self._halves = [np.zeros_like(weighted), np.zeros_like(weighted)]
            self._n, self._nb = np.zeros(y.shape[1:]), np.zeros(y.shape[1:], np.int64)
            self._half_n = np.zeros((2, *y.shape[1:]))
        else:
            self._p += spp * y
            self._q += spp * y * y
            self._c += spp * y * y[-1]
        assert self._n is not None and self._nb is not None and self._half_n is not None
        on = np.ones(y.shape[1:], bool) if mask is None else np.asarray(mask, bool)
        if on.shape != y.shape[1:]:
            raise ValueError(f"BatchAccumulator.add: mask must be {y.shape[1:]} pixels, got {on.shape}")
        second = self._half_n[0] > self._half_n[1]  # each pixel's batch goes to its half with fewer samples
        if mask is None and (second == second.flat[0]).all():
            self._halves[int(second.flat[0])] += weighted
        else:
            cell = self._per_cell(second)
            self._halves[0] += np.where(cell, 0.0, weighted)
            self._halves[1] += np.where(cell, weighted, 0.0)
        self._half_n[0] += np.where(on & ~second, spp, 0)
        self._half_n[1] += np.where(on & second, spp, 0)
        self._n += np.where(on, spp, 0)
        self._nb += on
        self.spp = int(self._n.max())
        self.batches = int(self._nb.max())

    def pixel_spp(self) -> np.ndarray:
        """(H, W): the samples each pixel has (they differ under per-pixel adaptive sampling)."""
        return np.zeros((0, 0)) if self._n is None else self._n.copy()

    def _per_cell(self, a: np.ndarray) -> np.ndarray:
        """A per-pixel (H, W) array as (1, H cells, W cells, 1), to divide (K, H, W, C) cell arrays."""
        return np.repeat(np.repeat(a, self.cells, axis=0), self.cells, axis=1)[None, ..., None]

    def mean(self) -> np.ndarray:
        """(K, H, W, C) float32: the estimate from every sample."""
        assert self._n is not None
        n = self.spp if (self._n == self.spp).all() else self._per_cell(np.maximum(self._n, 1))
        return ((self._halves[0] + self._halves[1]) / n).astype(np.float32)

    def noise(self) -> np.ndarray:
        """(K, H, W, C) float32: half the difference of the two halves' means.

        It has (in expectation) the variance of :meth:`mean`'s error where the
        halves hold equal sample counts; where one half is empty it is zero.
        """
        assert self._half_n is not None
        h0, h1 = self.halves()
        both = (self._half_n[0] > 0) & (self._half_n[1] > 0)
        if both.all():
            return 0.5 * (h0 - h1)
        return np.where(self._per_cell(both), 0.5 * (h0 - h1), 0.0).astype(np.float32)

    def halves(self) -> tuple[np.ndarray, np.ndarray]:
        """The two halves' means, (K, H, W, C) float32 each: independent estimates."""
        assert self._half_n is not None
        (h0, h1) = self._halves
        n0, n1 = (np.maximum(n, 1) for n in self._half_n)
        if (n0 == n0.flat[0]).all() and (n1 == n1.flat[0]).all():
            return (h0 / n0.flat[0]).astype(np.float32), (h1 / n1.flat[0]).astype(np.float32)
        return (h0 / self._per_cell(n0)).astype(np.float32), (h1 / self._per_cell(n1)).astype(np.float32)

    def se_ln(self, metric: str | None = None) -> np.ndarray:
        """(H, W): the largest standard error over the mixtures, of ``metric`` (default: the
        accumulator's), in ln units; inf before 2 batches."""
        metric = self.metric if metric is None else metric
        p, q, c = self._p, self._q, self._c
        if self.batches < 2 or p is None or q is None or c is None or self._n is None or self._nb is None:
            return np.full(p.shape[1:] if p is not None else (0, 0), np.inf)
        n: float | np.ndarray
        dof: int | np.ndarray
        if (self._nb == self.batches).all() and (self._n == self.spp).all():
            n, dof = float(self.spp), self.batches - 1
        else:  # per pixel (adaptive sampling); a pixel with fewer than 2 batches has an infinite error
            n, dof = self._n, np.where(self._nb >= 2, self._nb - 1, np.nan)
        mean = p / n
        var = np.maximum(q - n * mean * mean, 0.0) / dof  # per-sample variance, (M + 1, H, W)
        scale = np.abs(mean) + self.floor_rel * mean.reshape(len(mean), -1).mean(axis=1)[:, None, None]
        scale = np.where(scale > 0, scale, 1.0)  # 0 only in a black mixture (no light): no variance, error 0
        if metric == "absolute":
            rel_var = var / scale**2
        else:
            cov = (c - n * mean * mean[-1]) / dof
            rel_var = var / scale**2 + var[-1] / scale[-1] ** 2 - 2.0 * cov / (scale * scale[-1])
        se = np.sqrt(np.maximum(rel_var, 0.0) / n).max(axis=0)
        return se if np.isscalar(dof) else np.where(np.isnan(dof), np.inf, se)

    def percentiles(self, percentile: float, *, se: np.ndarray | None = None) -> dict:
        """Percentiles of the error map ``se`` (default: :meth:`se_ln`), and the other metric's at ``percentile``."""
        se = self.se_ln() if se is None else se
        other = "absolute" if self.metric == "flicker" else "flicker"
        return {**error_percentiles(se, percentile),
                f"{other}_at_percentile": float(np.percentile(self.se_ln(other), percentile))}


def error_percentiles(se: np.ndarray, percentile: float) -> dict:
    """p50, p90, p99, max and the ``percentile``-th percentile of an error map."""
    return {"p50": float(np.percentile(se, 50)), "p90": float(np.percentile(se, 90)),
            "p99": float(np.percentile(se, 99)), "max": float(se.max()),
            "at_percentile": float(np.percentile(se, percentile))}


def sample_se_ln(mixtures: np.ndarray, luminance: np.ndarray, error: np.ndarray, *, floor_rel: float,
                 metric: str = "flicker", window: int = 7) -> np.ndarray:
    """(H, W) ln standard error, largest over mixtures, from one error *sample* per pixel.

    For estimators whose batches are not independent and identically
    distributed (a denoised image), the batch statistics of
    :class:`BatchAccumulator` do not apply; what is left is an error sample
    ``error`` (K, H, W) of the group luminances ``luminance`` (K, H, W), e.g.
    half the difference of two independent halves. Its ln error per mixture
    (relative to ``Y + floor_rel * mean Y``; for ``"flicker"`` minus that of
    the all-ones reference mixture) is squared and averaged over a
    ``window`` x ``window`` box, a local estimate of the variance.
    """
    from scipy.ndimage import uniform_filter

    mixtures = np.vstack([np.asarray(mixtures, float), np.ones(np.shape(mixtures)[1])])
    y = np.tensordot(mixtures, np.asarray(luminance, float), axes=1)
    d = np.tensordot(mixtures, np.asarray(error, float), axes=1)
    scale = np.abs(y) + floor_rel * y.reshape(len(y), -1).mean(axis=1)[:, None, None]
    rel = d / np.where(scale > 0, scale, 1.0)  # 0 only in a black mixture (no light): error 0, not NaN
    if metric == "flicker":
        rel = rel - rel[-1]  # the reference row becomes 0 and drops out of the max
    return np.sqrt(uniform_filter(rel**2, size=(1, window, window), mode="nearest")).max(axis=0)


def next_batch_spp(total_spp: int, *, first: int, cap: int) -> int:
    """Samples per pixel of the next batch: ``first`` until ``BATCH_SPREAD`` batches, then about
    total / BATCH_SPREAD, a power of two, at most ``cap``."""
    size = first
    if total_spp >= BATCH_SPREAD * first:
        size = 2 ** int(math.floor(math.log2(total_spp / BATCH_SPREAD)))
    return int(max(1, min(size, cap)))


def needed_spp(spp: int, se_ln: float, target_ln: float) -> float:
    """Samples per pixel at which the error would meet the target (error ~ 1/sqrt(spp))."""
    if not math.isfinite(se_ln):
        return math.inf
    return spp * (se_ln / target_ln) ** 2


def summarize_quality(quality: list) -> dict:
    """Worst case over poses of the achieved noise (what every output records)."""
    if not quality:
        return {}
    se = {k: max(q["se_ln"][k] for q in quality) for k in quality[0]["se_ln"]}
    return {"spp_min": min(q["spp"] for q in quality), "spp_max": max(q["spp"] for q in quality),
            "se_ln": se, "percentile": quality[0]["percentile"], "target_ln": quality[0]["target_ln"],
            "reached": all(q["target_ln"] is None or q["se_ln"]["at_percentile"] <= q["target_ln"] for q in quality),
            "stopped_by": sorted({q["stopped_by"] for q in quality}),
            "denoised": any(q.get("denoised", False) for q in quality),
            "denoised_se_ln": ({k: max(q["denoised_se_ln"][k] for q in quality) for k in quality[0]["denoised_se_ln"]}
                               if quality[0].get("denoised_se_ln") else None),
            "render_s": float(sum(q["seconds"] for q in quality))}
