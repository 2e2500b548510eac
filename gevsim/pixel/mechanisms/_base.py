"""What a noise mechanism is (:class:`Mechanism`, one registry entry) and what the
photoreceptor kernel is fed (:class:`KernelNoise`, the coefficients every temporal
mechanism adds to)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

#: Upper bounds of noise parameters, far beyond any pixel (a preset's 1e300 gave inf or NaN signals after the
#: render): noise voltages of 1 V (a photoreceptor swings a few hundred mV), amplifier noise of 1e3 ln^2 Hz
#: (fitted DAVIS346: 0.058).
MAX_NOISE_V = 1.0
MAX_AMPLIFIER_NOISE_LN2_HZ = 1e3
#: The widest bandwidth of a pixel circuit's pole (1 GHz); 1e300 Hz gave inf and NaN after the render.
MAX_BANDWIDTH_HZ = 1e9

# Counter-based random streams of the photoreceptor kernel (gevsim.pixel._kernels): a draw is a hash of
# (run key, global step, stream, pixel). Fixed numbers: renumbering one changes every run's noise.
#: The photoreceptor pole's noise (shot and amplifier noise share it: their variances add).
STREAM_PHOTORECEPTOR = 1
#: The second deviate of the photoreceptor pole's noise on its way through the output pole.
STREAM_PHOTORECEPTOR_OUTPUT = 2
#: Output noise poles: pole m of :meth:`KernelNoise.poles` draws stream ``STREAM_OUTPUT_POLES + m``.
STREAM_OUTPUT_POLES = 3
#: The second deviate of the cascaded output pole (read noise) through the output pole.
STREAM_CASCADED_OUTPUT = 99


@dataclass
class KernelNoise:
    """The photoreceptor kernel's noise coefficients, summed over the mechanisms that are on.

    Attributes
    ----------
    shot_q : variance coefficient of noise on the photoreceptor pole that scales as f_c / I
        (shot noise: pi q per source of the photocurrent's shot noise).
    amp_ln2_hz : variance coefficient on that pole that scales as 1 / f_c (noise the loop pulls back).
    cascaded_hz, cascaded_var : Ornstein-Uhlenbeck poles that then pass the output pole
        (:mod:`gevsim.pixel._cascade`; the kernel has one such slot: the read noise).
    output_hz, output_var : Ornstein-Uhlenbeck poles added at the output (1/f).
    """

    shot_q: float = 0.0
    amp_ln2_hz: float = 0.0
    cascaded_hz: list[float] = field(default_factory=list)
    cascaded_var: list[float] = field(default_factory=list)
    output_hz: list[float] = field(default_factory=list)
    output_var: list[float] = field(default_factory=list)

    @property
    def on_photoreceptor_pole(self) -> bool:
        """Whether any noise drives the photoreceptor's own pole (it needs a finite bandwidth)."""
        return self.shot_q > 0 or self.amp_ln2_hz > 0

    @property
    def n_cascaded(self) -> int:
        """How many of :meth:`poles` (the first ones) pass the output pole: 0 or 1."""
        if len(self.cascaded_hz) > 1:
            raise ValueError(f"the photoreceptor kernel has one cascaded output-noise slot; {len(self.cascaded_hz)} "
                             "mechanisms asked for one")
        return len(self.cascaded_hz)

    def poles(self) -> tuple[np.ndarray, np.ndarray]:
        """Corner frequencies (Hz) and variances (ln^2) of every Ornstein-Uhlenbeck pole, cascaded first."""
        hz = np.asarray(self.cascaded_hz + self.output_hz, dtype=np.float64)
        var = np.asarray(self.cascaded_var + self.output_var, dtype=np.float64)
        return hz, var


@dataclass(frozen=True)
class Mechanism:
    """One noise mechanism of the pixel (an entry of :data:`gevsim.pixel.mechanisms.NOISE_MECHANISMS`).

    Attributes
    ----------
    params : its parameters dataclass; its fields are the preset keys it owns, in ``table``.
    table : the preset table (and parameter class) holding those keys: ``"noise"`` or ``"events"``.
    off : the values of its keys that switch it off; the ideal pixel (:meth:`SensorPreset.ideal`)
        has every mechanism's ``off``.
    source : where the model and its numbers come from.
    stream : which random numbers drive it (a kernel stream, a draw of a seeded Generator).
    temporal : ``temporal(params, volts_per_ln, plan)`` adds its coefficients to the photoreceptor
        kernel's :class:`KernelNoise` (temporal noise of the photoreceptor), or None.
    pattern : ``pattern(params, n, volts_per_ln, rng)``: a fixed pattern added to the photoreceptor's
        output (ln, float32 of n pixels), drawn after the temporal noise's start and only when on, so
        that a preset without it draws the numbers it drew before the mechanism existed; or None.
    where : the module that implements it where neither hook applies (event circuits).
    ideal_keeps : keys of ``off`` that :meth:`SensorPreset.ideal` leaves as the sensor has them, each with
        why (empty: the ideal pixel has the mechanism off).
    """

    params: type
    table: str
    off: Mapping[str, Any]
    source: str
    stream: str
    temporal: Callable[[Any, float, KernelNoise], None] | None = None
    pattern: Callable[[Any, int, float, np.random.Generator], np.ndarray] | None = None
    where: str = ""
    ideal_keeps: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self):
        keys = self.keys
        if set(self.off) - set(keys) or set(self.ideal_keeps) - set(self.off):
            raise ValueError(f"{self.params.__name__}: off state names keys it does not own: "
                             f"{sorted(set(self.off) - set(keys))}, or ideal_keeps keys not in its off state: "
                             f"{sorted(set(self.ideal_keeps) - set(self.off))}")

    @property
    def keys(self) -> tuple[str, ...]:
        """The preset keys it owns (its parameters' fields)."""
        return tuple(f.name for f in fields(self.params))

    def is_on(self, params: Any) -> bool:
        """Whether ``params`` (a preset's table) has it on: any of its ``off`` keys differs."""
        return any(getattr(params, k) != v for k, v in self.off.items())
