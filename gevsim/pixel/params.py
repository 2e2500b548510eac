"""Parameters of the pixel front end: photoreceptor, noise, event circuits.

Frozen dataclasses with SI units in the field names. ``ln`` units are natural
log of photocurrent: a photoreceptor voltage V maps to V / (n U_T).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from gevsim._validate import real
from gevsim.config import FieldError, FromTable
from gevsim.pixel.mechanisms import NOISE_MECHANISMS
from gevsim.pixel.mechanisms._base import MAX_BANDWIDTH_HZ, MAX_NOISE_V  # noqa: F401 (the limits' home before #33)
from gevsim.pixel.mechanisms.amplifier import AmplifierNoise
from gevsim.pixel.mechanisms.comparator_offset import ComparatorOffset
from gevsim.pixel.mechanisms.dark_current import MAX_DARK_CURRENT_SPREAD, DarkCurrent  # noqa: F401
from gevsim.pixel.mechanisms.dc_offset import DcOffset
from gevsim.pixel.mechanisms.flicker import FlickerNoise
from gevsim.pixel.mechanisms.leak import Leak
from gevsim.pixel.mechanisms.mismatch import ThresholdMismatch
from gevsim.pixel.mechanisms.prnu import Prnu
from gevsim.pixel.mechanisms.read import ReadNoise
from gevsim.pixel.mechanisms.reset import ResetNoise
from gevsim.pixel.mechanisms.shot import ShotNoise
from gevsim.pixel.thermal import MAX_TEMPERATURE_K, REFERENCE_TEMPERATURE_K, thermal_factor

if TYPE_CHECKING:  # numpy is imported where it is used
    import numpy as np
    from numpy.typing import ArrayLike

__all__ = ["REFERENCE_TEMPERATURE_K", "EventParams", "NoiseParams", "PhotoreceptorParams", "ReadoutParams",
           "thermal_factor"]


def _check_mechanisms(params: Any, table: str) -> None:
    """Run the validation of every registered mechanism of ``table`` on ``params`` (a class built from
    their dataclasses: each base's ``__post_init__`` checks its own keys)."""
    for mechanism in NOISE_MECHANISMS.values():
        if mechanism.table == table:
            mechanism.params.__post_init__(params)  # type: ignore[attr-defined]


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
        from scipy.constants import Boltzmann, elementary_charge  # here: reading a preset needs no scipy

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



#: The longest readout latency (and its jitter): 1 s, beyond any arbiter (us to ms); 1e300 s overflowed the
#: int64 microsecond timestamps.
MAX_LATENCY_S = 1.0


@dataclass(frozen=True)
class NoiseParams(DcOffset, Prnu, DarkCurrent, FlickerNoise, ReadNoise, AmplifierNoise, ShotNoise, FromTable):
    """A preset's ``[noise]`` table: the keys of every noise mechanism of the photoreceptor, one base
    class per entry of :data:`gevsim.pixel.mechanisms.NOISE_MECHANISMS` (fields gather from the last base
    to the first; each base documents and
    validates its keys: :mod:`gevsim.pixel.mechanisms.shot`, ``amplifier``, ``read``, ``flicker``,
    ``dark_current``, ``prnu``, ``dc_offset``)."""

    TABLE = "noise"

    def __post_init__(self):
        _check_mechanisms(self, "noise")


@dataclass(frozen=True)
class EventParams(ComparatorOffset, Leak, ResetNoise, ThresholdMismatch, FromTable):
    """Event-circuit parameters used by the event emulators: the comparators' own (below) and the keys of
    the event-circuit noise mechanisms, one base class each (:mod:`gevsim.pixel.mechanisms.mismatch`,
    ``reset``, ``leak``, ``comparator_offset``).

    Parameters
    ----------
    threshold_on_ln, threshold_off_ln : contrast thresholds in ln units.
    refractory_s : time the change amplifier is held in reset after an event (changes during it
        are forgotten, Lichtsteiner et al. 2008).
    """

    TABLE = "events"

    threshold_on_ln: float = 0.2
    threshold_off_ln: float = 0.2
    refractory_s: float = 0.0

    def __post_init__(self):
        real(self.threshold_on_ln, "threshold_on_ln", low=0, low_open=True)
        real(self.threshold_off_ln, "threshold_off_ln", low=0, low_open=True)
        real(self.refractory_s, "refractory_s", low=0)
        _check_mechanisms(self, "events")


#: The arbiters a readout may name (:data:`gevsim.events.arbiter.ARBITERS`, which checks it has these).
ARBITRATIONS = ("row_burst", "row_column", "row_queue")


@dataclass(frozen=True)
class ReadoutParams(FromTable):
    """Event readout of a sensor (a preset's ``[readout]`` table).

    Parameters
    ----------
    max_rate_eps : events per second the arbiter and bus deliver at the most (``inf``: no limit).
    max_delay_s : the longest an event waits to be read before it is dropped (``inf``: never).
    arbitration : how the arbiter picks the next pixel (:data:`gevsim.events.arbiter.ARBITERS`: ``row_burst``
        for DAVIS, ``row_column`` for DVS128, ``row_queue`` for Prophesee Gen4).
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
    arbitration: str = "row_burst"
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
        if self.arbitration not in ARBITRATIONS:
            raise FieldError("arbitration", f"arbitration must be one of {', '.join(ARBITRATIONS)}, "
                                            f"got {self.arbitration!r}")
