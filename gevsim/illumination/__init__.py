"""Lamp waveforms, flicker metrics and light-group mixing.

Waveforms are functions of time (s) with mean 1 that scale a light group's
mean radiance; the irradiance is ``E(t) = sum_k w_k(t) B_k(pose(t))`` (see DESIGN.md).
"""

from .base import DC, Waveform
from .basic import PWM, Sinusoid
from .mains import Fluorescent, Incandescent, MainsLamp, SodiumHID
from .metrics import flicker_index, modulation_spectrum, percent_flicker
from .mix import mix, mix_poses, weights_at
from .spec import WAVEFORMS, from_spec
from .table import Table

__all__ = [
    "Waveform", "DC", "Sinusoid", "PWM", "MainsLamp", "Fluorescent", "Incandescent",
    "SodiumHID", "Table", "WAVEFORMS", "from_spec",
    "percent_flicker", "flicker_index", "modulation_spectrum", "mix", "mix_poses", "weights_at",
]
