"""Shot noise of the photocurrent: the photodiode's, and the feedback transistor's that carries
the same current (Schottky: one-sided PSD 2 q I; in the log domain 2 q / I, through the
photoreceptor's first-order pole of cutoff f_c: variance pi q f_c / I per source).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from gevsim._validate import FieldError
from gevsim.pixel.mechanisms._base import KernelNoise


@dataclass(frozen=True)
class ShotNoise:
    """shot_noise : photon/photocurrent shot noise (PSD 2 q I) through the photoreceptor filter.
    feedback_shot_noise : the photoreceptor's feedback transistor carries the photocurrent too and adds
    equal shot noise (variance x2; Graca, McReynolds & Delbruck 2023: the photoreceptor's noise is within
    2x of photon shot noise)."""

    shot_noise: bool = True
    feedback_shot_noise: bool = False

    def __post_init__(self):
        n = type(self).__name__
        for name in ("feedback_shot_noise", "shot_noise"):
            if not isinstance(getattr(self, name), bool):
                raise FieldError(name, f"{n}.{name} must be true or false, got {getattr(self, name)!r}")


def shot_noise_factor(noise: Any) -> float:
    """How many equal shot-noise sources the photocurrent drives: the photodiode, and with
    ``feedback_shot_noise`` the photoreceptor's feedback transistor (same current, variance x2)."""
    return 2.0 if noise.feedback_shot_noise else 1.0


def temporal(noise: Any, volts_per_ln: float, plan: KernelNoise) -> None:
    """pi q per source on the photoreceptor pole (the feedback transistor's only with the photodiode's)."""
    from scipy.constants import elementary_charge  # here: reading a preset needs no scipy

    if noise.shot_noise:
        plan.shot_q += math.pi * elementary_charge * shot_noise_factor(noise)
