"""Parameters of the pixel front end: photoreceptor, noise, event circuits.

Frozen dataclasses with SI units in the field names. ``ln`` units are natural
log of photocurrent: a photoreceptor voltage V maps to V / (n U_T).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from scipy.constants import Boltzmann, elementary_charge

from gevsim._validate import real
from gevsim.config import FieldError, FromTable

if TYPE_CHECKING:  # numpy is imported where it is used
    import numpy as np
    from numpy.typing import ArrayLike


#: Temperature (K) at which presets state dark current and leak rates (27 degC).
REFERENCE_TEMPERATURE_K = 300.0
#: The hottest sensor: 500 K, above any silicon chip's rating (~400 K); 1e300 K overflowed the leakage to NaN.
MAX_TEMPERATURE_K = 500.0
#: The widest bandwidth of a pixel circuit's pole (1 GHz); 1e300 Hz gave inf and NaN after the render.
MAX_BANDWIDTH_HZ = 1e9


def thermal_factor(temperature_k: float, doubling_k: float) -> float:
    """2 ** ((T - T_ref) / doubling_k): how much a leakage current grows from
    :data:`REFERENCE_TEMPERATURE_K` to ``temperature_k`` (1 for an infinite doubling interval)."""
    if math.isinf(doubling_k):
        return 1.0
    from gevsim._portable import exp_scalar

    return float(exp_scalar((temperature_k - REFERENCE_TEMPERATURE_K) / doubling_k * 0.6931471805599453))  # ln 2


@dataclass(frozen=True)
class PhotoreceptorParams(FromTable):
    """Logarithmic photoreceptor V = V0 + n U_T ln(I_ph + I_dark) with a first-order
    low-pass whose cutoff grows in proportion to photocurrent up to ``max_cutoff_hz``
    (Delbruck & Mead 1994; Lichtsteiner, Posch & Delbruck 2008).

    Parameters
    ----------
    cutoff_hz : cutoff at ``cutoff_ref_photocurrent_a`` (scales linearly with current).
    cutoff_ref_photocurrent_a : photocurrent at which the cutoff is ``cutoff_hz``.
    max_cutoff_hz : amplifier-limited maximum cutoff (``inf``: none).
    second_pole_hz : the output pole (source follower, change-amplifier input), or None; every
        noise passes it after its own pole (:mod:`gevsim.pixel._cascade`).
    slope_factor : n, the subthreshold slope factor (1/kappa).
    temperature_k : for the thermal voltage U_T = k T / q.
    v0_v : output voltage at a total photocurrent of 1 A (an offset only).
    """

    TABLE = "photoreceptor"

    cutoff_hz: float = 3000.0
    cutoff_ref_photocurrent_a: float = 1e-12
    max_cutoff_hz: float = 10000.0
    second_pole_hz: float | None = None
    slope_factor: float = 1.4
    temperature_k: float = 300.0
    v0_v: float = 2.5

    def __post_init__(self):
        real(self.cutoff_hz, "cutoff_hz", low=0, low_open=True, allow_inf=True)
        real(self.cutoff_ref_photocurrent_a, "cutoff_ref_photocurrent_a", low=0, low_open=True)
        real(self.max_cutoff_hz, "max_cutoff_hz", low=0, low_open=True, allow_inf=True)
        if self.second_pole_hz is not None:
            real(self.second_pole_hz, "second_pole_hz", low=0, low_open=True, high=MAX_BANDWIDTH_HZ)
        real(self.slope_factor, "slope_factor", low=0, low_open=True)
        real(self.temperature_k, "temperature_k", low=0, low_open=True, high=MAX_TEMPERATURE_K)
        real(self.v0_v, "v0_v")

    @property
    def thermal_voltage_v(self) -> float:
        return Boltzmann * self.temperature_k / elementary_charge

    @property
    def volts_per_ln(self) -> float:
        """n U_T: volts per unit of ln(photocurrent)."""
        return self.slope_factor * self.thermal_voltage_v

    def cutoff_at(self, photocurrent_a: ArrayLike) -> np.ndarray:
        """Cutoff frequency (Hz) at a total photocurrent (A): proportional, then capped."""
        import numpy as np

        i = np.asarray(photocurrent_a, float)
        if math.isinf(self.cutoff_hz):
            return np.full_like(i, self.max_cutoff_hz)
        return np.minimum(self.cutoff_hz * i / self.cutoff_ref_photocurrent_a, self.max_cutoff_hz)



#: Upper bounds of noise parameters, far beyond any pixel (a preset's 1e300 gave inf or NaN signals after the
#: render): noise voltages of 1 V (a photoreceptor swings a few hundred mV), amplifier noise of 1e3 ln^2 Hz
#: (fitted DAVIS346: 0.058) and a read-noise bandwidth of :data:`MAX_BANDWIDTH_HZ`.
MAX_NOISE_V = 1.0
MAX_AMPLIFIER_NOISE_LN2_HZ = 1e3
#: The longest readout latency (and its jitter): 1 s, beyond any arbiter (us to ms); 1e300 s overflowed the
#: int64 microsecond timestamps.
MAX_LATENCY_S = 1.0


#: The largest DSNU (lognormal sigma of the dark current). The lognormal keeps its mean at ``dark_current_a``, so
#: its median is exp(-sigma^2 / 2) of it: 1 % at sigma = 3, a 20-fold spread per sigma, far beyond measured DSNU
#: (tens of %). Above it pixels' dark currents underflow to 0 (sigma = 1000 did: ln of 0 in black pixels).
MAX_DARK_CURRENT_SPREAD = 3.0


@dataclass(frozen=True)
class NoiseParams(FromTable):
    """Pixel noise sources.

    Parameters
    ----------
    shot_noise : photon/photocurrent shot noise (PSD 2 q I) through the photoreceptor filter.
    read_noise_v : readout/comparator voltage noise (rms, volts) at the output, band-limited by its
        own pole at ``read_noise_bandwidth_hz`` and then by the output pole (``second_pole_hz``).
    dark_current_a : mean dark current (A); also sets the floor of the log response.
    dark_current_spread : DSNU, lognormal sigma of the per-pixel dark current (fixed pattern), at most
        :data:`MAX_DARK_CURRENT_SPREAD`.
    prnu : photo response non-uniformity, relative sigma of the per-pixel gain (fixed pattern).
    flicker_noise_v : rms of optional 1/f voltage noise between the two corner frequencies (0: off).
    feedback_shot_noise : the photoreceptor's feedback transistor carries the photocurrent too and adds
        equal shot noise (variance x2; Graca, McReynolds & Delbruck 2023: the photoreceptor's noise is
        within 2x of photon shot noise).
    dark_current_doubling_k : the dark current doubles every this many kelvin above
        :data:`REFERENCE_TEMPERATURE_K` (inf: no temperature dependence).
    amplifier_noise_ln2_hz : the photoreceptor amplifier's noise that its feedback loop does not
        suppress (ln^2 Hz). The amplifier's current noise on its output node is pulled back by the
        loop at the closed-loop cutoff f_c, an Ornstein-Uhlenbeck process of fixed diffusion: its
        variance is this / f_c, so it rises as the light (and f_c) falls. This is the mechanism that
        makes background activity rise steeply in the dark (Graca & Delbruck 2021's "paradox": shot
        noise alone has a light-independent variance where f_c ~ I).
    dc_offset_v : sigma (volts) of the photoreceptors' DC output offsets (fixed pattern, from the
        feedback transistors' threshold mismatch). A DVS is AC-coupled and does not see it; gradient
        comparators and the centre-surround DVS compare neighbours' levels and do.
    """

    TABLE = "noise"

    shot_noise: bool = True
    read_noise_v: float = 0.0
    read_noise_bandwidth_hz: float = 10000.0
    dark_current_a: float = 1e-15
    dark_current_spread: float = 0.0
    prnu: float = 0.0
    flicker_noise_v: float = 0.0
    flicker_noise_low_hz: float = 1.0
    flicker_noise_high_hz: float = 1000.0
    feedback_shot_noise: bool = False
    dark_current_doubling_k: float = math.inf
    dc_offset_v: float = 0.0
    amplifier_noise_ln2_hz: float = 0.0

    def __post_init__(self):
        n = type(self).__name__
        if not isinstance(self.feedback_shot_noise, bool):
            raise FieldError("feedback_shot_noise",
                             f"{n}.feedback_shot_noise must be true or false, got {self.feedback_shot_noise!r}")
        real(self.dark_current_doubling_k, "dark_current_doubling_k", low=0, low_open=True, allow_inf=True)
        real(self.dc_offset_v, "dc_offset_v", low=0, high=MAX_NOISE_V)
        real(self.amplifier_noise_ln2_hz, "amplifier_noise_ln2_hz", low=0, high=MAX_AMPLIFIER_NOISE_LN2_HZ)
        if not isinstance(self.shot_noise, bool):
            raise FieldError("shot_noise", f"{n}.shot_noise must be true or false, got {self.shot_noise!r}")
        for name in ("read_noise_v", "dark_current_a", "dark_current_spread", "flicker_noise_v"):
            real(getattr(self, name), name, low=0, high=MAX_NOISE_V if name.endswith("_v") else None)
        if self.dark_current_spread > MAX_DARK_CURRENT_SPREAD:
            raise FieldError("dark_current_spread", f"dark_current_spread = {self.dark_current_spread!r} is above "
                             f"{MAX_DARK_CURRENT_SPREAD:g}: a lognormal that wide has its median under 1 % of the mean "
                             "dark current, and dark pixels' currents underflow to 0 A")
        real(self.prnu, "prnu", low=0, high=0.5)
        real(self.read_noise_bandwidth_hz, "read_noise_bandwidth_hz", low=0, low_open=True, high=MAX_BANDWIDTH_HZ)
        real(self.flicker_noise_low_hz, "flicker_noise_low_hz", low=0, low_open=True)
        real(self.flicker_noise_high_hz, "flicker_noise_high_hz", low=0, low_open=True)
        if self.flicker_noise_high_hz <= self.flicker_noise_low_hz:
            raise FieldError("flicker_noise_high_hz", f"{n}.flicker_noise_high_hz must exceed flicker_noise_low_hz, "
                             f"got {self.flicker_noise_high_hz!r} <= {self.flicker_noise_low_hz!r}")



@dataclass(frozen=True)
class EventParams(FromTable):
    """Event-circuit parameters used by the event emulators.

    Parameters
    ----------
    threshold_on_ln, threshold_off_ln : contrast thresholds in ln units.
    threshold_mismatch_ln : per-comparator fixed-pattern sigma of the thresholds (ln units).
    refractory_s : time the change amplifier is held in reset after an event (changes during it
        are forgotten, Lichtsteiner et al. 2008).
    reset_noise_ln : sigma (ln units) of the level's error at each release from reset (kTC and
        charge-injection noise; IEBCS redraws a threshold of sigma 0.01-0.02 after every event).
    leak_rate_hz : mean rate of leak (ON) events per pixel in the dark at :data:`REFERENCE_TEMPERATURE_K`;
        leak_rate_spread its relative sigma (lognormal, so that no pixel's rate is clipped to zero).
    leak_light_hz_per_a : leak rate added per ampere of photocurrent (parasitic photocurrent in the reset
        switch's junction: leak rises with light; Nozaki & Delbruck, IEEE TED 2017).
    leak_doubling_k : the leak rate doubles every this many kelvin above :data:`REFERENCE_TEMPERATURE_K`
        (junction leakage; inf: no temperature dependence).
    comparator_offset_v : sigma (volts) of the gradient comparators' input offsets (fixed pattern):
        an offset moves a comparator's +theta and -theta together.
    """

    TABLE = "events"

    threshold_on_ln: float = 0.2
    threshold_off_ln: float = 0.2
    threshold_mismatch_ln: float = 0.0
    refractory_s: float = 0.0
    reset_noise_ln: float = 0.0
    leak_rate_hz: float = 0.0
    leak_rate_spread: float = 0.0
    leak_light_hz_per_a: float = 0.0
    leak_doubling_k: float = math.inf
    comparator_offset_v: float = 0.0

    def __post_init__(self):
        real(self.leak_light_hz_per_a, "leak_light_hz_per_a", low=0)
        real(self.leak_doubling_k, "leak_doubling_k", low=0, low_open=True, allow_inf=True)
        real(self.comparator_offset_v, "comparator_offset_v", low=0)
        real(self.threshold_on_ln, "threshold_on_ln", low=0, low_open=True)
        real(self.threshold_off_ln, "threshold_off_ln", low=0, low_open=True)
        for name in ("threshold_mismatch_ln", "refractory_s", "reset_noise_ln", "leak_rate_hz", "leak_rate_spread"):
            real(getattr(self, name), name, low=0)


@dataclass(frozen=True)
class ReadoutParams(FromTable):
    """Event readout of a sensor (a preset's ``[readout]`` table).

    Parameters
    ----------
    max_rate_eps : events per second the arbiter and bus deliver at the most (``inf``: no limit).
    max_delay_s : the longest an event waits to be read before it is dropped (``inf``: never).
    latency_s : the fixed delay from a comparator's crossing to its request reaching the arbiter
        (comparator, handshake): the latency floor.
    latency_jitter_s : sigma of that delay's spread from event to event (a normal, truncated at
        +-3 sigma and at zero delay).
    rate_controller_eps : the on-chip event-rate controller's target (Prophesee ESP "ERC", an option of
        the IMX636; ``inf``: off): events beyond it are dropped, spread evenly over each reference period.
    rate_controller_period_s : its reference period.
    anti_flicker : the on-chip anti-flicker filter (Prophesee ESP "AFK", an IMX636 option;
        :mod:`gevsim.events.antiflicker`): events of 4x4-pixel blocks flickering between
        ``anti_flicker_min_hz`` and ``anti_flicker_max_hz`` are dropped; ``anti_flicker_cycles`` periods
        within ``anti_flicker_tolerance`` of each other mark a block.
    """

    TABLE = "readout"

    max_rate_eps: float = math.inf
    max_delay_s: float = math.inf
    latency_s: float = 0.0
    latency_jitter_s: float = 0.0
    rate_controller_eps: float = math.inf
    rate_controller_period_s: float = 200e-6
    anti_flicker: bool = False
    anti_flicker_min_hz: float = 50.0
    anti_flicker_max_hz: float = 500.0
    anti_flicker_cycles: int = 4
    anti_flicker_tolerance: float = 0.1

    def __post_init__(self):
        if not isinstance(self.anti_flicker, bool):
            raise FieldError("anti_flicker", f"anti_flicker must be true or false, got {self.anti_flicker!r}")
        real(self.anti_flicker_min_hz, "anti_flicker_min_hz", low=0, low_open=True)
        real(self.anti_flicker_max_hz, "anti_flicker_max_hz", low=self.anti_flicker_min_hz, low_open=True)
        if isinstance(self.anti_flicker_cycles, bool) or not isinstance(self.anti_flicker_cycles, int) \
                or self.anti_flicker_cycles < 1:
            raise FieldError("anti_flicker_cycles",
                             f"anti_flicker_cycles must be an integer >= 1, got {self.anti_flicker_cycles!r}")
        real(self.anti_flicker_tolerance, "anti_flicker_tolerance", low=0, low_open=True, high=1.0)
        real(self.rate_controller_eps, "rate_controller_eps", low=0, low_open=True, allow_inf=True)
        real(self.rate_controller_period_s, "rate_controller_period_s", low=0, low_open=True)
        real(self.latency_s, "latency_s", low=0, high=MAX_LATENCY_S)
        real(self.latency_jitter_s, "latency_jitter_s", low=0, high=MAX_LATENCY_S)
        real(self.max_rate_eps, "max_rate_eps", low=0, low_open=True, allow_inf=True)
        real(self.max_delay_s, "max_delay_s", low=0, allow_inf=True)
