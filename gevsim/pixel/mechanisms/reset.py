"""Reset noise: the memorised level's error at each release from reset (kTC and charge-injection
noise; IEBCS, Joubert et al., Front. Neurosci. 2021, redraws a threshold of sigma 0.01-0.02 after
every event). Implemented by the brightness-event kernel (:mod:`gevsim.events._kernels`)."""

from __future__ import annotations

from dataclasses import dataclass

from gevsim._validate import real


@dataclass(frozen=True)
class ResetNoise:
    """reset_noise_ln : sigma (ln units) of the level's error at each release from reset."""

    reset_noise_ln: float = 0.0

    def __post_init__(self):
        real(self.reset_noise_ln, "reset_noise_ln", low=0)
