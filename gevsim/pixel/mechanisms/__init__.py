"""The pixel's noise mechanisms: one registry entry each (as :data:`gevsim.events.readout.READOUT_STAGES`).

Each entry names its parameters dataclass (the preset keys it owns), the preset table those keys
live in, its off state, its source and the random numbers that drive it. Temporal noise of the
photoreceptor reaches the one compiled kernel (:func:`gevsim.pixel._kernels.photoreceptor`) as
coefficients summed by :func:`kernel_noise`; fixed patterns added to the output come from each
entry's ``pattern``; event-circuit mechanisms are implemented by the event emulators and listed
here for their parameters, off state and source. The ideal pixel is every entry off
(:meth:`gevsim.pixel.presets.SensorPreset.ideal`).

Adding a mechanism (docs/sensors.md, "Adding a noise mechanism"): write its module here (its
parameters dataclass with validation in ``__post_init__``, and a ``temporal`` or ``pattern`` hook),
add one entry below, and add its dataclass to the bases of the table's class in
:mod:`gevsim.pixel.params` (``NoiseParams`` or ``EventParams``); tests/pixel/test_mechanisms.py
checks that every entry is wired, and that the ideal pixel has it off.
"""

from __future__ import annotations

from typing import Any

from gevsim.pixel.mechanisms import (
    amplifier,
    comparator_offset,
    dark_current,
    dc_offset,
    flicker,
    leak,
    mismatch,
    prnu,
    read,
    reset,
    shot,
)
from gevsim.pixel.mechanisms._base import KernelNoise, Mechanism

__all__ = ["NOISE_MECHANISMS", "KernelNoise", "Mechanism", "ideal_values", "kernel_noise", "mechanisms_on"]

#: Why the ideal pixel keeps the gradient comparators' offsets: a fixed pattern, as the pre-registry ideal kept
#: it (gradient noise-free office 64x48: 114-122 ev/px/s with it, 123 without); a counterfactual that drops it
#: changes what "noise-induced" counts, which is issue 35's sensitivity study to decide.
_KEEPS_OFFSETS = "a fixed pattern of the comparators that the noise-free counterfactual has kept (issue 35)"

#: Noise mechanisms by name, in the order their temporal coefficients and patterns are gathered (the read
#: noise before the 1/f poles: its pole is the kernel's cascaded slot).
NOISE_MECHANISMS: dict[str, Mechanism] = {
    "shot": Mechanism(
        shot.ShotNoise, "noise", {"shot_noise": False, "feedback_shot_noise": False},
        "Schottky (PSD 2 q I); feedback transistor: Graca, McReynolds & Delbruck 2023",
        "kernel streams 1 (photoreceptor pole) and 2 (through the output pole)", temporal=shot.temporal),
    "amplifier": Mechanism(
        amplifier.AmplifierNoise, "noise", {"amplifier_noise_ln2_hz": 0.0},
        "Graca & Delbruck 2021 (arXiv 2109.08640): noise rises as f_c falls",
        "kernel streams 1 and 2 (shared with shot noise: the variances add)", temporal=amplifier.temporal),
    "read": Mechanism(
        read.ReadNoise, "noise", {"read_noise_v": 0.0}, "assumed: readout and comparator noise, band-limited",
        "kernel stream 3 (its pole) and 99 (through the output pole); its start: the Photoreceptor's rng",
        temporal=read.temporal),
    "flicker": Mechanism(
        flicker.FlickerNoise, "noise", {"flicker_noise_v": 0.0}, "McWhorter's 1/f construction (one pole a decade)",
        "kernel streams 3 + m for output pole m (after the read noise's); starts: the Photoreceptor's rng",
        temporal=flicker.temporal),
    "dark_current": Mechanism(
        dark_current.DarkCurrent, "noise", {"dark_current_spread": 0.0},
        "DSNU (EMVA 1288), lognormal; junction leakage doubling with temperature",
        "the Photoreceptor's rng: fixed_pattern's second draw (drawn also when off)"),
    "prnu": Mechanism(
        prnu.Prnu, "noise", {"prnu": 0.0}, "PRNU (EMVA 1288)",
        "the Photoreceptor's rng: fixed_pattern's first draw (drawn also when off)"),
    "dc_offset": Mechanism(
        dc_offset.DcOffset, "noise", {"dc_offset_v": 0.0},
        "Pelgrom et al., JSSC 1989 (threshold mismatch of the feedback transistors)",
        "the Photoreceptor's rng, last draw, only when on", pattern=dc_offset.pattern),
    "threshold_mismatch": Mechanism(
        mismatch.ThresholdMismatch, "events", {"threshold_mismatch_ln": 0.0},
        "Lichtsteiner, Posch & Delbruck, JSSC 2008 (2.1 %)", "each event emulator's rng (its first draws)",
        where="gevsim.events.brightness.per_pixel_thresholds"),
    "reset": Mechanism(
        reset.ResetNoise, "events", {"reset_noise_ln": 0.0}, "IEBCS (Joubert et al. 2021): sigma 0.01-0.02",
        "the DVS kernel's counter-based stream of reset_key (drawn from the emulator's rng)",
        where="gevsim.events._kernels.brightness"),
    "leak": Mechanism(
        leak.Leak, "events", {"leak_rate_hz": 0.0, "leak_light_hz_per_a": 0.0},
        "Nozaki & Delbruck, IEEE TED 2017 (leak rises with temperature and light)",
        "the DVS emulator's rng: rates after the thresholds, then the phases", where="gevsim.events.brightness"),
    "comparator_offset": Mechanism(
        comparator_offset.ComparatorOffset, "events", {"comparator_offset_v": 0.0},
        "Pelgrom et al., JSSC 1989 (offset of a differential pair); assumed sigma", "the gradient emulator's rng",
        where="gevsim.events.gradient.GradientEmulator", ideal_keeps={"comparator_offset_v": _KEEPS_OFFSETS}),
}


def kernel_noise(noise: Any, volts_per_ln: float) -> KernelNoise:
    """The photoreceptor kernel's noise coefficients: every temporal mechanism of ``noise`` (a
    preset's :class:`~gevsim.pixel.params.NoiseParams`) adds its share, in registry order."""
    plan = KernelNoise()
    for mechanism in NOISE_MECHANISMS.values():
        if mechanism.temporal is not None and mechanism.table == "noise":
            mechanism.temporal(noise, volts_per_ln, plan)
    return plan


def ideal_values(table: str) -> dict[str, Any]:
    """The ideal pixel's values of one preset table (``"noise"`` or ``"events"``): every mechanism's off
    state, but for the keys an entry's ``ideal_keeps`` says why it keeps (the light leak, the comparator
    offsets; the dark leak goes)."""
    return {k: v for m in NOISE_MECHANISMS.values() if m.table == table for k, v in m.off.items()
            if k not in m.ideal_keeps}


def mechanisms_on(noise: Any, events: Any) -> list[str]:
    """Names of the mechanisms a sensor has on."""
    tables = {"noise": noise, "events": events}
    return [name for name, m in NOISE_MECHANISMS.items() if m.is_on(tables[m.table])]
