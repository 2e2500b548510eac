"""The photoreceptors' DC output offsets: a fixed pattern from the feedback transistors' threshold
mismatch (Pelgrom, Duinmaijer & Welbers, IEEE JSSC 1989). A DVS is AC-coupled and does not see it;
gradient comparators and the centre-surround DVS compare neighbours' levels and do."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from gevsim._validate import real
from gevsim.pixel.mechanisms._base import MAX_NOISE_V


@dataclass(frozen=True)
class DcOffset:
    """dc_offset_v : sigma (volts) of the photoreceptors' DC output offsets."""

    dc_offset_v: float = 0.0

    def __post_init__(self):
        real(self.dc_offset_v, "dc_offset_v", low=0, high=MAX_NOISE_V)


def pattern(noise: Any, n: int, volts_per_ln: float, rng: np.random.Generator) -> np.ndarray:
    """Each pixel's offset (ln units, float32): a normal of sigma dc_offset_v / n U_T."""
    return (noise.dc_offset_v / volts_per_ln * rng.standard_normal(n)).astype(np.float32)
