"""Pixel front end: logarithmic photoreceptor, noise, sensor presets, APS frames."""

from gevsim.pixel.aps import ApsParams, ApsSensor, exposure_electrons, photon_transfer, system_gain_from_ptc
from gevsim.pixel.mechanisms import NOISE_MECHANISMS
from gevsim.pixel.noise import fixed_pattern, flicker_noise_poles, shot_noise_variance_ln
from gevsim.pixel.params import EventParams, NoiseParams, PhotoreceptorParams
from gevsim.pixel.photoreceptor import Photoreceptor
from gevsim.pixel.presets import SensorPreset, load_preset, preset_names

__all__ = [
    "NOISE_MECHANISMS",
    "ApsParams",
    "ApsSensor",
    "SensorPreset",
    "exposure_electrons",
    "load_preset",
    "photon_transfer",
    "preset_names",
    "system_gain_from_ptc",
    "EventParams",
    "NoiseParams",
    "Photoreceptor",
    "PhotoreceptorParams",
    "fixed_pattern",
    "flicker_noise_poles",
    "shot_noise_variance_ln",
]
