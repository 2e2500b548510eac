"""Registry of event emulators: the one place that names them.

Each entry says which HDF5 stream an emulator writes, how the driver builds it
from an emulation config and a sensor preset, which slot of the run's seed
sequence seeds it, the dataclass of its config table (if it has parameters of
its own), how frame mode builds it (if it can run on frames), what kind of events
it makes, its role in the study report and the colour plots draw it in
(colour-science's ``*_METHODS`` pattern, as :data:`gevsim.illumination.WAVEFORMS`).

Adding an emulator is its module in :mod:`gevsim.events` plus one entry in
:data:`EMULATORS`, and where it has parameters: their frozen dataclass here
(a :class:`~gevsim.config.FromTable` with ``TABLE`` its config table) and one flat
field per parameter in :class:`~gevsim.emulation.config.EmulationConfig`, whose
default is the dataclass's (checked when that module is imported). Configs,
reports and aggregation take it from here.

The seed slots are fixed: a run with the same seed draws the same numbers for the
same emulator whichever others run beside it (:data:`SEED_SLOTS` is computed).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gevsim._validate import FieldError, real, real_list
from gevsim.config import FromTable
from gevsim.errors import suggest
from gevsim.events import BrightnessEmulator, CenterSurroundEmulator, GradientEmulator
from gevsim.events.center_surround import MAX_SURROUND_LENGTH_PX
from gevsim.events.gradient import LN_THRESHOLDS
from gevsim.pixel.params import EventParams

__all__ = ["APS_READ_SEED", "APS_SEED", "EMULATORS", "FRAME_EMULATORS", "HEADLINE", "PARAMS", "PHOTORECEPTOR_SEED",
           "READOUT_SEED", "SEED_SLOTS", "STREAMS", "Emulator", "GradientConfig", "SurroundConfig", "check_emulator",
           "check_emulator_list", "make_emulator"]

#: Slots of ``SeedSequence(seed).spawn(SEED_SLOTS)`` used outside the emulators.
PHOTORECEPTOR_SEED = 0
APS_SEED = 5
APS_READ_SEED = 6
READOUT_SEED = 7


@dataclass(frozen=True)
class GradientConfig(FromTable):
    """``[gradient]``: the comparators of both gradient emulators (plain and resolution compression).

    Parameters
    ----------
    thresholds_ln : comparator thresholds (ln units), pixel ``(x, y)`` gets number ``(x + y) mod n``
        (default :data:`gevsim.events.gradient.LN_THRESHOLDS`).
    hysteresis_ln : comparator hysteresis (0: the paper's definition); below the smallest threshold.
    """

    TABLE = "gradient"
    thresholds_ln: tuple[float, ...] = LN_THRESHOLDS
    hysteresis_ln: float = 0.0

    def __post_init__(self) -> None:
        raw_t, raw_h = self.thresholds_ln, self.hysteresis_ln
        object.__setattr__(self, "thresholds_ln", real_list(raw_t, "thresholds_ln", positive=True))
        object.__setattr__(self, "hysteresis_ln", real(raw_h, "hysteresis_ln", low=0.0))
        if self.hysteresis_ln >= min(self.thresholds_ln):
            raise FieldError("hysteresis_ln", f"hysteresis_ln = {raw_h} must be below the smallest threshold "
                                              f"{min(raw_t)}")


@dataclass(frozen=True)
class SurroundConfig(FromTable):
    """``[csdvs]``: the centre-surround emulator's surround (:mod:`gevsim.events.center_surround`).

    Parameters
    ----------
    surround_length_px : space constant of the diffuser, in pixels (> 0).
    surround_tau_s : time constant of the surround (0: instantaneous).
    """

    TABLE = "csdvs"
    surround_length_px: float = 2.0
    surround_tau_s: float = 1e-3

    def __post_init__(self) -> None:
        object.__setattr__(self, "surround_length_px", real(self.surround_length_px, "surround_length_px", low=0.0,
                                                            low_open=True, high=MAX_SURROUND_LENGTH_PX))
        object.__setattr__(self, "surround_tau_s", real(self.surround_tau_s, "surround_tau_s", low=0.0))


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
    kind : the events it makes: ``"brightness"`` (ON/OFF log-intensity changes), ``"gradient"``
        (spatial gradient codes) or ``"center_surround"``; reports group streams by it.
    params : the dataclass of its config table (``params.TABLE``), or None where it has none.
    headline : its role in the study report's comparison: ``"baseline"`` or ``"candidate"`` (the
        rejection ratio is the baseline's flicker-induced rate over the candidate's), or "".
    even_size : needs an even height and width (resolution compression).
    decodes : its events are decoded from stored thresholds and an initial state (gradient codes).
    build_frames : ``build_frames(shape, *, thresholds, dvs_params, rng)``: the emulator of frame
        mode, or None where it does not run on frames.
    log_input : frame mode feeds it the log of the frames (:func:`~gevsim.emulation.frames.log_intensity`;
        else the linear frames).
    thresholds : ``thresholds(emulator, preset)``: what the emulation file stores under
        ``/thresholds/<name>`` for reconstruction, or None for nothing.
    bridges : its ``process`` takes a ``bridge`` (crossings between long steps, ``crossings = "bridge"``:
        :mod:`gevsim.emulation.bridging`).
    """

    stream: str
    seed_slot: int
    build: Callable[..., Any]
    color: str
    label: str
    kind: str
    params: type[FromTable] | None = None
    headline: str = ""
    even_size: bool = False
    decodes: bool = False
    build_frames: Callable[..., Any] | None = None
    log_input: bool = False
    thresholds: Callable[[Any, Any], np.ndarray] | None = None
    bridges: bool = False


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
        p = config.params(GradientConfig)
        return GradientEmulator(shape, thresholds_ln=p.thresholds_ln, rc=rc,
                                offset_sigma_ln=preset.events.comparator_offset_v / preset.photoreceptor.volts_per_ln,
                                hysteresis_ln=p.hysteresis_ln, rng=rng)
    return build


def _csdvs(shape, *, config, preset, rng):
    p = config.params(SurroundConfig)
    return CenterSurroundEmulator(shape, preset.events, surround_length_px=p.surround_length_px,
                                  surround_tau_s=p.surround_tau_s, rng=rng, cold_start=config.cold_start,
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
    "dvs": Emulator("events", 1, _dvs, "tab:red", "DVS", "brightness", headline="baseline",
                    build_frames=_dvs_frames, log_input=True, thresholds=_dvs_nominal, bridges=True),
    "gradient": Emulator("gradient_events", 2, _gradient(False), "tab:blue", "gradient", "gradient", GradientConfig,
                         headline="candidate", decodes=True, build_frames=_gradient_frames(False), thresholds=_theta,
                         bridges=True),
    "gradient_rc": Emulator("gradient_rc_events", 3, _gradient(True), "tab:cyan", "gradient RC", "gradient",
                            GradientConfig, even_size=True, decodes=True, build_frames=_gradient_frames(True),
                            thresholds=_theta),
    "csdvs": Emulator("csdvs_events", 4, _csdvs, "tab:green", "CSDVS", "center_surround", SurroundConfig),
}
#: HDF5 stream of each emulator.
STREAMS: dict[str, str] = {name: e.stream for name, e in EMULATORS.items()}
#: The parameter dataclasses of the emulators' config tables, each once, in registry order.
PARAMS: tuple[type[FromTable], ...] = tuple(dict.fromkeys(e.params for e in EMULATORS.values() if e.params))


def _seed_slots() -> int:
    """How many children of the run's seed sequence a run spawns; refuses two users of one slot."""
    users = {"photoreceptor": PHOTORECEPTOR_SEED, "aps": APS_SEED, "aps read": APS_READ_SEED, "readout": READOUT_SEED,
             **{name: e.seed_slot for name, e in EMULATORS.items()}}
    taken: dict[int, str] = {}
    for name, slot in users.items():
        if slot in taken:
            raise ValueError(f"seed slot {slot} is {taken[slot]}'s and {name}'s: give {name} a free one")
        taken[slot] = name
    return max(taken) + 1


#: Children of ``SeedSequence(seed)`` a run spawns. ``SeedSequence.spawn(n)[i]`` does not depend on ``n``:
#: a slot added later leaves the earlier slots' draws as they were.
SEED_SLOTS = _seed_slots()


def _headline(role: str) -> str:
    names = [name for name, e in EMULATORS.items() if e.headline == role]
    if len(names) != 1:
        raise ValueError(f"the registry needs one {role} emulator for the study report, has {names}")
    return names[0]


#: The emulators the study report compares: (baseline, candidate); the flicker rejection ratio is the
#: baseline's flicker-induced rate over the candidate's.
HEADLINE: tuple[str, str] = (_headline("baseline"), _headline("candidate"))
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
