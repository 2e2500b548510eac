"""The one tone mapping from log irradiance to [0, 1] display frames.

Every reconstruction of a sequence, and its ground truth, goes through the
same map, fixed by the ground truth: ln-units between the 1st and 99th
percentile of all ground-truth frames map linearly to [0, 1] (clipped).
Frame-mode sequences are already [0, 1] intensities and use the identity.
The metrics (EVREAL's MSE and SSIM on [0, 1] frames) are computed after it.
It depends on nothing above it, so the evaluation, the plots and the EVREAL export all take it from here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gevsim._validate import real, real_array


@dataclass(frozen=True)
class ToneMap:
    """display = clip((L - low) / (high - low), 0, 1); identity when low = 0, high = 1."""

    low: float = 0.0
    high: float = 1.0

    def __post_init__(self):
        real(self.low, "low")
        if not real(self.high, "high") > self.low:
            raise ValueError(f"tone map needs low < high, got low={self.low!r}, high={self.high!r}")

    @classmethod
    def from_ground_truth(cls, log_frames: np.ndarray, *, percentiles: tuple[float, float] = (1.0, 99.0)) -> ToneMap:
        """Fixed by the ground-truth log frames (all of them together)."""
        values = real_array(log_frames, "log_frames", dtype=np.float64)
        if values.size == 0:
            raise ValueError("ground-truth frames must be non-empty")
        low, high = np.percentile(values, percentiles)
        if high <= low:  # a flat image: centre it
            low, high = low - 0.5, high + 0.5
        return cls(float(low), float(high))

    def __call__(self, log_frames: np.ndarray) -> np.ndarray:
        x = (np.asarray(log_frames, dtype=np.float64) - self.low) / (self.high - self.low)
        return np.clip(x, 0.0, 1.0)
