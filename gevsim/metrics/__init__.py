"""Metrics: image quality as EVREAL computes it, and event-stream bandwidth."""

from gevsim.metrics.bandwidth import bits_per_second, events_per_second
from gevsim.metrics.quality import (
    SSIM_KWARGS,
    TS_TOL_US,
    aggregate,
    frame_metrics,
    lpips,
    lpips_available,
    lpips_unavailable_reason,
    mse,
    pair_by_timestamp,
    psnr,
    sequence_metrics,
    ssim,
)

__all__ = [
    "SSIM_KWARGS",
    "TS_TOL_US",
    "aggregate",
    "bits_per_second",
    "events_per_second",
    "frame_metrics",
    "lpips",
    "lpips_available",
    "lpips_unavailable_reason",
    "mse",
    "pair_by_timestamp",
    "psnr",
    "sequence_metrics",
    "ssim",
]
