"""Dark current: the photodiode's leakage, the floor of the log response ln(I_ph + I_dark), with
its per-pixel spread (DSNU, lognormal, fixed pattern) and its growth with temperature (silicon
junction leakage doubles every ~6-8 K). Off means no spread: the mean stays, a black pixel has no
finite response without it."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from gevsim._validate import FieldError, real
from gevsim.pixel.thermal import REFERENCE_TEMPERATURE_K, thermal_factor

#: The largest DSNU (lognormal sigma of the dark current). The lognormal keeps its mean at ``dark_current_a``, so
#: its median is exp(-sigma^2 / 2) of it: 1 % at sigma = 3, a 20-fold spread per sigma, far beyond measured DSNU
#: (tens of %). Above it pixels' dark currents underflow to 0 (sigma = 1000 did: ln of 0 in black pixels).
MAX_DARK_CURRENT_SPREAD = 3.0


@dataclass(frozen=True)
class DarkCurrent:
    """dark_current_a : mean dark current (A) at :data:`REFERENCE_TEMPERATURE_K`.
    dark_current_spread : DSNU, lognormal sigma of the per-pixel dark current, at most
    :data:`MAX_DARK_CURRENT_SPREAD`. dark_current_doubling_k : it doubles every this many kelvin
    (inf: no temperature dependence)."""

    dark_current_a: float = 1e-15
    dark_current_spread: float = 0.0
    dark_current_doubling_k: float = math.inf

    def __post_init__(self):
        real(self.dark_current_doubling_k, "dark_current_doubling_k", low=0, low_open=True, allow_inf=True)
        for name in ("dark_current_a", "dark_current_spread"):
            real(getattr(self, name), name, low=0)
        if self.dark_current_spread > MAX_DARK_CURRENT_SPREAD:
            raise FieldError("dark_current_spread", f"dark_current_spread = {self.dark_current_spread!r} is above "
                             f"{MAX_DARK_CURRENT_SPREAD:g}: a lognormal that wide has its median under 1 % of the mean "
                             "dark current, and dark pixels' currents underflow to 0 A")


def dark_current_a(noise: Any, temperature_k: float = REFERENCE_TEMPERATURE_K) -> float:
    """Mean dark current (A) at ``temperature_k``: ``dark_current_a`` (stated at
    :data:`~gevsim.pixel.thermal.REFERENCE_TEMPERATURE_K`) doubling every ``dark_current_doubling_k``."""
    return noise.dark_current_a * thermal_factor(temperature_k, noise.dark_current_doubling_k)
