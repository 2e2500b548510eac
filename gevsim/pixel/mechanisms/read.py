"""Read noise: the readout's and comparators' voltage noise at the photoreceptor output, band-limited
by its own pole at ``read_noise_bandwidth_hz`` and then by the output pole (``second_pole_hz``), so that
its level-crossing statistics do not depend on the time step (:mod:`gevsim.pixel._cascade`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from gevsim._validate import real
from gevsim.pixel.mechanisms._base import MAX_BANDWIDTH_HZ, MAX_NOISE_V, KernelNoise


@dataclass(frozen=True)
class ReadNoise:
    """read_noise_v : rms (volts) at the output; read_noise_bandwidth_hz : its own pole."""

    read_noise_v: float = 0.0
    read_noise_bandwidth_hz: float = 10000.0

    def __post_init__(self):
        real(self.read_noise_v, "read_noise_v", low=0, high=MAX_NOISE_V)
        real(self.read_noise_bandwidth_hz, "read_noise_bandwidth_hz", low=0, low_open=True, high=MAX_BANDWIDTH_HZ)


def temporal(noise: Any, volts_per_ln: float, plan: KernelNoise) -> None:
    """One pole at ``read_noise_bandwidth_hz`` of variance (read_noise_v / n U_T)^2, cascaded through
    the output pole."""
    if noise.read_noise_v > 0:
        v = noise.read_noise_v / volts_per_ln
        plan.cascaded_hz.append(noise.read_noise_bandwidth_hz)
        plan.cascaded_var.append(v * v)
