"""Leak events: the reset switch's junction leakage drifts the memorised level down, giving ON
events at a rate that rises with temperature and with light (parasitic photocurrent; Nozaki &
Delbruck, IEEE TED 2017). Implemented by :class:`gevsim.events.brightness.BrightnessEmulator`
(:func:`~gevsim.events.brightness.leak_rates`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from gevsim._validate import real


@dataclass(frozen=True)
class Leak:
    """leak_rate_hz : mean rate of leak (ON) events per pixel in the dark at the reference temperature;
    leak_rate_spread its relative sigma (lognormal, so that no pixel's rate is clipped to zero).
    leak_light_hz_per_a : leak rate added per ampere of photocurrent. leak_doubling_k : the leak rate
    doubles every this many kelvin (inf: no temperature dependence)."""

    leak_rate_hz: float = 0.0
    leak_rate_spread: float = 0.0
    leak_light_hz_per_a: float = 0.0
    leak_doubling_k: float = math.inf

    def __post_init__(self):
        real(self.leak_light_hz_per_a, "leak_light_hz_per_a", low=0)
        real(self.leak_doubling_k, "leak_doubling_k", low=0, low_open=True, allow_inf=True)
        for name in ("leak_rate_hz", "leak_rate_spread"):
            real(getattr(self, name), name, low=0)
