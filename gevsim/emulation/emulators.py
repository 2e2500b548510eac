"""Registry of event emulators: the one place that names them.

Each entry says which HDF5 stream an emulator writes, how the driver builds it
from an emulation config and a sensor preset, which slot of the run's seed
sequence seeds it, how frame mode builds it (if it can run on frames) and the
colour plots draw it in. Adding an emulator is its module in :mod:`gevsim.events`
plus one entry in :data:`EMULATORS` (colour-science's ``*_METHODS`` pattern, as
:data:`gevsim.illumination.WAVEFORMS`).

The seed slots are fixed: a run with the same seed draws the same numbers for the
same emulator whichever others run beside it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gevsim.errors import suggest
from gevsim.events import BrightnessEmulator, CenterSurroundEmulator, GradientEmulator
from gevsim.pixel.params import EventParams

__all__ = ["APS_READ_SEED", "APS_SEED", "EMULATORS", "FRAME_EMULATORS", "PHOTORECEPTOR_SEED", "READOUT_SEED",
           "SEED_SLOTS",
           "STREAMS", "Emulator", "check_emulator", "check_emulator_list", "make_emulator"]

#: Slots of ``SeedSequence(seed).spawn(SEED_SLOTS)`` used outside the emulators.
PHOTORECEPTOR_SEED = 0
APS_SEED = 5
APS_READ_SEED = 6
READOUT_SEED = 7
SEED_SLOTS = 8  # SeedSequence.spawn(n)[i] does not depend on n: earlier slots draw as before


@dataclass(frozen=True)
class Emulator:
    """One registry entry.

    Attributes
    ----------
    stream : HDF5 group of its events.
    seed_slot : which child of the run's seed sequence seeds it.
    build : ``build(shape, *, config, preset, rng)``: the emulator of an emulation
        (``config`` an :class:`~gevsim.emulation.EmulationConfig`, ``preset`` a sensor preset).
    color : matplotlib colour of its curves.
    label : its name in report sentences.
    even_size : needs an even height and width (resolution compression).
    decodes : its events are decoded from stored thresholds and an initial state (gradient codes).
    build_frames : ``build_frames(shape, *, thresholds, dvs_params, rng)``: the emulator of frame
        mode, or None where it does not run on frames.
    log_input : frame mode feeds it the log of the frames (:func:`~gevsim.emulation.frames.log_intensity`;
        else the linear frames).
    thresholds : ``thresholds(emulator, preset)``: what the emulation file stores under
        ``/thresholds/<name>`` for reconstruction, or None for nothing.
    """

    stream: str
    seed_slot: int
    build: Callable[..., Any]
    color: str
    label: str
    even_size: bool = False
    decodes: bool = False
    build_frames: Callable[..., Any] | None = None
    log_input: bool = False
    thresholds: Callable[[Any, Any], np.ndarray] | None = None


def _dvs(shape, *, config, preset, rng):
    return BrightnessEmulator(shape, preset.events, rng=rng, cold_start=config.cold_start,
                              temperature_k=preset.photoreceptor.temperature_k)


def _dvs_nominal(emulator, preset) -> np.ndarray:
    """The sensor's nominal ON/OFF contrast steps (brightness-event reconstruction integrates them)."""
    return np.array([preset.events.threshold_on_ln, preset.events.threshold_off_ln])


def _theta(emulator, preset) -> np.ndarray:
    """The per-pixel threshold map decoding needs."""
    return emulator.theta.astype(np.float32)


def _gradient(rc: bool):
    def build(shape, *, config, preset, rng):
        return GradientEmulator(shape, thresholds_ln=config.thresholds_ln, rc=rc,
                                offset_sigma_ln=preset.events.comparator_offset_v / preset.photoreceptor.volts_per_ln,
                                hysteresis_ln=config.hysteresis_ln, rng=rng)
    return build


def _csdvs(shape, *, config, preset, rng):
    return CenterSurroundEmulator(shape, preset.events, surround_length_px=config.surround_length_px,
                                  surround_tau_s=config.surround_tau_s, rng=rng, cold_start=config.cold_start,
                                  temperature_k=preset.photoreceptor.temperature_k)


def _dvs_frames(shape, *, thresholds: Sequence[float], dvs_params: EventParams, rng: np.random.Generator):
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    return BrightnessEmulator(shape, dvs_params, rng=rng)


def _gradient_frames(rc: bool):
    def build(shape, *, thresholds: Sequence[float], dvs_params: EventParams, rng: np.random.Generator):
        return GradientEmulator(shape, thresholds_ln=thresholds, rc=rc, interpolate=False)  # frame units
    return build


#: Event emulators by the name used in configs, in the order they run and are reported.
EMULATORS: dict[str, Emulator] = {
    "dvs": Emulator("events", 1, _dvs, "tab:red", "DVS", build_frames=_dvs_frames, log_input=True,
                    thresholds=_dvs_nominal),
    "gradient": Emulator("gradient_events", 2, _gradient(False), "tab:blue", "gradient", decodes=True,
                         build_frames=_gradient_frames(False), thresholds=_theta),
    "gradient_rc": Emulator("gradient_rc_events", 3, _gradient(True), "tab:cyan", "gradient RC", even_size=True,
                            decodes=True, build_frames=_gradient_frames(True), thresholds=_theta),
    "csdvs": Emulator("csdvs_events", 4, _csdvs, "tab:green", "CSDVS"),
}
#: HDF5 stream of each emulator.
STREAMS: dict[str, str] = {name: e.stream for name, e in EMULATORS.items()}
#: The emulators frame mode can run.
FRAME_EMULATORS: tuple[str, ...] = tuple(name for name, e in EMULATORS.items() if e.build_frames is not None)


def check_emulator(name: str, choices: Sequence[str] = tuple(EMULATORS)) -> Emulator:
    """The registry entry of ``name``; ValueError with a did-you-mean when it is not among ``choices``."""
    if not isinstance(name, str) or name not in choices:
        raise ValueError(f"unknown emulator {name!r}{suggest(str(name), choices)}; choose from {', '.join(choices)}")
    return EMULATORS[name]


def check_emulator_list(value: Any, choices: Sequence[str] = tuple(EMULATORS)) -> tuple[str, ...]:
    """A non-empty list of emulator names from ``choices`` as a tuple (duplicates dropped); ValueError
    (with a did-you-mean) naming what is wrong otherwise."""
    if isinstance(value, tuple):
        value = list(value)
    if not isinstance(value, list) or not value:
        raise ValueError(f"expected a non-empty list drawn from {list(choices)}, got {value!r}")
    for name in value:
        check_emulator(name, choices)
    return tuple(dict.fromkeys(value))


def make_emulator(name: str, shape: tuple[int, int], *, config: Any, preset: Any, rng: np.random.Generator) -> Any:
    """Build the emulator ``name`` of an emulation (the dispatcher of :data:`EMULATORS`)."""
    return check_emulator(name).build(tuple(shape), config=config, preset=preset, rng=rng)
