"""The photoreceptor amplifier's noise that its feedback loop does not suppress (Graca & Delbruck
2021, arXiv 2109.08640: the "paradox" that background activity rises steeply in the dark, where shot
noise alone has a light-independent variance because f_c ~ I).

The amplifier's current noise on its output node is pulled back by the loop at the closed-loop
cutoff f_c: an Ornstein-Uhlenbeck process of fixed diffusion, variance ``amplifier_noise_ln2_hz / f_c``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from gevsim._validate import real
from gevsim.pixel.mechanisms._base import MAX_AMPLIFIER_NOISE_LN2_HZ, KernelNoise


@dataclass(frozen=True)
class AmplifierNoise:
    """amplifier_noise_ln2_hz : the diffusion (ln^2 Hz) of the amplifier noise the loop leaves; its
    variance on the photoreceptor pole is this / f_c."""

    amplifier_noise_ln2_hz: float = 0.0

    def __post_init__(self):
        real(self.amplifier_noise_ln2_hz, "amplifier_noise_ln2_hz", low=0, high=MAX_AMPLIFIER_NOISE_LN2_HZ)


def temporal(noise: Any, volts_per_ln: float, plan: KernelNoise) -> None:
    plan.amp_ln2_hz += noise.amplifier_noise_ln2_hz
