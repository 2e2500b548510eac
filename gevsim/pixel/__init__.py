"""Pixel front end: logarithmic photoreceptor, noise, sensor presets, APS frames.

The names below are imported on first use (:mod:`gevsim._lazy`): reading a preset does not compile
or load the photoreceptor's kernels.
"""

from gevsim._lazy import attach

TYPE_CHECKING = False
if TYPE_CHECKING:
    from gevsim.pixel.aps import ApsParams, ApsSensor, exposure_electrons, photon_transfer, system_gain_from_ptc
    from gevsim.pixel.mechanisms import NOISE_MECHANISMS
    from gevsim.pixel.noise import fixed_pattern, flicker_noise_poles, shot_noise_variance_ln
    from gevsim.pixel.params import EventParams, NoiseParams, PhotoreceptorParams
    from gevsim.pixel.photoreceptor import Photoreceptor
    from gevsim.pixel.presets import SensorPreset, load_preset, preset_names

__getattr__, __dir__ = attach(__name__, {
    **dict.fromkeys(("ApsParams", "ApsSensor", "exposure_electrons", "photon_transfer", "system_gain_from_ptc"),
                    "aps"),
    "NOISE_MECHANISMS": "mechanisms",
    **dict.fromkeys(("fixed_pattern", "flicker_noise_poles", "shot_noise_variance_ln"), "noise"),
    **dict.fromkeys(("EventParams", "NoiseParams", "PhotoreceptorParams"), "params"),
    "Photoreceptor": "photoreceptor",
    **dict.fromkeys(("SensorPreset", "load_preset", "preset_names"), "presets"),
})

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
